"""First-order Gauss-Markov term x(k) = a x(k-1) + g w(k) in numpy alone, chunk invariant.

Why not scipy.signal.lfilter: the device model imports the generator, and a chip should not
pay for importing scipy (issue 10, cold start). A Python loop over samples is 100x too slow,
so the recursion is evaluated on super-blocks of S = L x nb samples by two levels of scaled
cumulative sums. Inside a block of L samples starting at sample b with value s = x(b - 1):

    x(b + j) = a^(j+1) [ s + P_j ],   P_j = sum_{i <= j} g a^-(i+1) w(b + i)

and the block starts follow the same recursion one level up (A = a^L, E = P_(L-1)):
s_(c+1) = A (s_c + E_c), solved the same way. The blocks are the rows of an (nb, L) array
in sample order, summed across one column at a time: L vector adds of nb independent sums
(a 1-D np.cumsum, or np.cumsum along an axis, is 10-50x slower). L = 16 and nb = 2048 at most, and a^-S <= e^500,
so no scaled term overflows; the rounding of the partial sums is below (L + nb) eps ~ 5e-13
of the term's std.

Chunk invariance: the term computes whole super-blocks only, counted from the start or the
last rate change, whatever the caller asks for, and keeps the normals it drew for them;
sample k is always driven by the k-th normal of the term's own stream. Against the
sample-by-sample recursion of earlier versions (lfilter) the values differ by rounding
only: the same normals, the same process (a test compares them).

A term with T < dt / 40 has a < 4e-18: to double precision it is white noise g w, and is
computed as such. The random walk of the noise model is the same recursion with a = 1
(walk_coefficients): a 1-D np.cumsum costs about as much as drawing its normals; its factors
of exactly 1 are skipped (the same values: multiplying by 1.0 is exact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

_LOG_RANGE = 500.0  # a^-S <= e^500 ~ 1e217: the scaled terms stay far from overflow
_BLOCK = 16  # L: samples per block (rows of the (L, nb) layout)
_MAX_BLOCKS = 2048  # nb: blocks per super-block (S <= 32768)
_WHITE_ABOVE = 40.0  # dt / T above this: a < e^-40 = 4e-18, white to double precision


@dataclass(frozen=True, eq=False)
class PoleCoefficients:
    """Per-sample coefficients of one term at one sample period, with its block tables."""

    a: complex  # exp(-dt / T); a resonance's complex pole r e^(i w0)
    g: float  # B sqrt(1 - a^2): stationary std B
    size: int  # S, samples per super-block
    up: np.ndarray | None  # (L, 1): g a^-(j+1)   (None: white)
    down: np.ndarray | None  # (L, 1): a^(j+1)
    up_blocks: np.ndarray | None  # (nb - 1,): A^-c, c = 0 .. nb-2
    down_blocks: np.ndarray | None  # (nb - 1,): A^b, b = 1 .. nb-1


def pole_coefficients(B: float, dt: float, T: float) -> PoleCoefficients:
    """The tables of the term (B deg/s, T s) at sample period dt s."""
    r = dt / T
    a = math.exp(-r)
    return _tables(a, B * math.sqrt(1.0 - a * a), r)


def walk_coefficients(step: float) -> PoleCoefficients:
    """The tables of a random walk x(k) = x(k-1) + step w(k): the same recursion, a = 1."""
    return _tables(1.0, step, 0.0)


def _tables(a: float, g: float, r: float) -> PoleCoefficients:
    if r > _WHITE_ABOVE:
        return PoleCoefficients(a, g, _BLOCK * _MAX_BLOCKS, None, None, None, None)
    L = int(min(_BLOCK, _LOG_RANGE // r)) if r > 0 else _BLOCK
    nb = int(max(1, min(_MAX_BLOCKS, _LOG_RANGE // (L * r)))) if r > 0 else _MAX_BLOCKS
    j = np.arange(1, L + 1, dtype=float)[:, None]
    c = np.arange(nb - 1, dtype=float)
    return PoleCoefficients(
        a=a,
        g=g,
        size=L * nb,
        up=g * np.exp(r * j),
        down=np.exp(-r * j),
        up_blocks=np.exp(L * r * c),
        down_blocks=np.exp(-L * r * (c + 1.0)),
    )


@dataclass(frozen=True, eq=False)
class ResonanceCoefficients:
    """A resonator x(k) = a1 x(k-1) + a2 x(k-2) + g w(k) as the real part of a complex
    first-order recursion: with poles p, conj(p), partial fractions give
    x(k) = Re(scale y(k)), y(k) = p y(k-1) + w(k), scale = 2 g p / (p - conj(p)); y is a
    complex Gauss-Markov term, so the block recursion above computes it (complex tables)."""

    tables: PoleCoefficients
    scale: complex
    stationary: np.ndarray  # (2, 2): Cholesky factor of the covariance of (Re y, Im y)


def resonance_coefficients(f0_hz: float, width_hz: float, B: float, dt: float
                           ) -> ResonanceCoefficients | None:
    """The tables of a resonator (centre f0 Hz, -3 dB width Hz, std B deg/s, noise.
    resonant_bands) at sample period dt; None when f0 is not below the Nyquist frequency."""
    if not f0_hz < 0.5 / dt:
        return None
    radius = math.exp(-math.pi * width_hz * dt)
    w0 = 2.0 * math.pi * f0_hz * dt
    p = radius * complex(math.cos(w0), math.sin(w0))
    a1, a2 = 2.0 * radius * math.cos(w0), -radius * radius
    unit = (1.0 - a2) / ((1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1))  # AR(2) variance per g^2
    g = B / math.sqrt(unit)
    r = -complex(math.log(radius), w0)  # p = exp(-r)
    L = int(min(_BLOCK, _LOG_RANGE // r.real)) if r.real > 0 else _BLOCK
    nb = int(max(1, min(_MAX_BLOCKS, _LOG_RANGE // (L * r.real)))) if r.real > 0 else _MAX_BLOCKS
    j = np.arange(1, L + 1, dtype=float)[:, None]
    c = np.arange(nb - 1, dtype=float)
    tables = PoleCoefficients(a=p, g=1.0, size=L * nb, up=np.exp(r * j), down=np.exp(-r * j),
                              up_blocks=np.exp(L * r * c),
                              down_blocks=np.exp(-L * r * (c + 1.0)))
    # stationary y = sum_j p^j w(-j): E|y|^2 = 1 / (1 - |p|^2), E y^2 = 1 / (1 - p^2)
    e_abs = 1.0 / (1.0 - radius * radius)
    e_sq = 1.0 / (1.0 - p * p)
    cov = np.array([[(e_abs + e_sq.real) / 2.0, e_sq.imag / 2.0],
                    [e_sq.imag / 2.0, (e_abs - e_sq.real) / 2.0]])
    return ResonanceCoefficients(tables, 2.0 * g * p / (p - p.conjugate()),
                                 np.linalg.cholesky(cov))


def _superblock(c: PoleCoefficients, w: np.ndarray, s0: complex) -> np.ndarray:
    """Values of the term over one super-block driven by w (S normals) from x(-1) = s0."""
    if c.up is None:
        return w * c.g
    assert c.down is not None and c.up_blocks is not None and c.down_blocks is not None
    L = c.up.shape[0]
    nb = w.shape[0] // L
    # (nb, L) in sample order: row b is block b; summed across the columns one column at a
    # time (L strided vector adds of nb sums), so no transposed copy is made on the way in
    # or out (tools/bench_noise_generation.py: 1.8x faster than the (L, nb) layout, the same
    # sums in the same order)
    Y = np.multiply(w.reshape(nb, L), c.up.T)
    for j in range(1, L):
        np.add(Y[:, j - 1], Y[:, j], out=Y[:, j])
    walk = c.a == 1.0  # the random walk: every block and decay factor is exactly 1
    starts = np.empty(nb, dtype=Y.dtype)  # complex for a resonance
    starts[0] = s0
    if nb > 1 and walk:
        np.cumsum(Y[:-1, -1], out=starts[1:])
        starts[1:] += s0
    elif nb > 1:
        q = Y[:-1, -1] * c.up_blocks
        np.cumsum(q, out=q)
        q += s0
        np.multiply(q, c.down_blocks, out=starts[1:])
    Y += starts[:, None]
    if not walk:
        Y *= c.down.T
    return Y.reshape(L * nb)


class Pole:
    """One Gauss-Markov term with its own random stream, served in any chunks."""

    __slots__ = ("coef", "last", "normals", "pos", "queue", "rng", "values")

    def __init__(self, rng: np.random.Generator, B: float | None) -> None:
        self.rng = rng
        # start in the stationary distribution (std B): a powered sensor has been running
        # long before the first sample; a random walk (B None) starts at 0
        self.last: complex = B * float(rng.standard_normal()) if B is not None else 0.0
        self.coef: PoleCoefficients | None = None
        self.queue = np.empty(0)  # normals drawn ahead, not yet in a computed super-block
        self.normals = np.empty(0)  # normals of the current super-block
        self.values = np.empty(0)  # its values
        self.pos = 0  # next value to hand out within the super-block

    def state(self) -> tuple[Any, ...]:
        """Everything needed to continue exactly (arrays are replaced, never written)."""
        return (self.rng.bit_generator.state, self.coef, self.queue, self.normals, self.values,
                self.pos, self.last)

    def set_state(self, state: tuple[Any, ...]) -> None:
        rng_state, self.coef, self.queue, self.normals, self.values, self.pos, self.last = state
        self.rng.bit_generator.state = rng_state

    def restart(self, coef: PoleCoefficients) -> None:
        """Continue from the last value handed out with new coefficients (a rate change):
        the normals drawn ahead stay queued, the next sample opens a super-block."""
        if self.pos < self.normals.size:
            self.queue = np.concatenate([self.normals[self.pos :], self.queue])
        self.normals = self.values = np.empty(0)
        self.pos = 0
        self.coef = coef

    def skip(self, n: int) -> None:
        """Advance by n samples without handing them out."""
        self.take(n)

    def take(self, n: int) -> np.ndarray:
        """The next n values (deg/s)."""
        if n and self.pos == self.values.size:
            self._next_superblock()
        if self.pos + n <= self.values.size:  # the common case: a view, no copy
            out = self.values[self.pos : self.pos + n]
            self.pos += n
        else:
            out = np.empty(n, dtype=self.values.dtype)  # complex for a resonance
            done = 0
            while done < n:
                if self.pos == self.values.size:
                    self._next_superblock()
                m = min(n - done, self.values.size - self.pos)
                out[done : done + m] = self.values[self.pos : self.pos + m]
                self.pos += m
                done += m
        if n:
            self.last = out[-1].item()  # a float, or a resonance's complex state
        return out

    def _next_superblock(self) -> None:
        c = self.coef
        assert c is not None
        s0 = self.values[-1].item() if self.values.size else self.last
        if self.queue.size == 0:  # the common case: no normals left over from a rate change
            w = self.rng.standard_normal(c.size)
        elif self.queue.size >= c.size:
            w, self.queue = self.queue[: c.size], self.queue[c.size :]
        else:
            w = np.concatenate([self.queue, self.rng.standard_normal(c.size - self.queue.size)])
            self.queue = np.empty(0)
        self.normals = w
        self.values = _superblock(c, w, s0)
        self.pos = 0


class ResonancePole(Pole):
    """One resonator of a band (ResonanceCoefficients): a complex Gauss-Markov term with its
    own stream, started in its stationary distribution at its first coefficients (two normals
    drawn first); ``take`` hands out the real output."""

    __slots__ = ("scale", "start")

    def __init__(self, rng: np.random.Generator) -> None:
        super().__init__(rng, None)
        self.start: np.ndarray | None = rng.standard_normal(2)
        self.scale = 0j

    def restart_resonance(self, coef: ResonanceCoefficients | None) -> None:
        """New coefficients (the first, or a rate change); None: its centre is above this
        rate's Nyquist frequency, and it is silent there."""
        if coef is not None and self.start is not None:
            z = coef.stationary @ self.start
            self.last = complex(float(z[0]), float(z[1]))
            self.start = None
        self.restart(coef.tables if coef is not None else None)  # type: ignore[arg-type]
        self.scale = coef.scale if coef is not None else 0j

    def state(self) -> tuple[Any, ...]:
        return (super().state(), self.scale, self.start)

    def set_state(self, state: tuple[Any, ...]) -> None:
        inner, self.scale, self.start = state
        super().set_state(inner)

    def take(self, n: int) -> np.ndarray:
        if self.coef is None:
            return np.zeros(n)
        return (super().take(n) * self.scale).real
