"""The chip's data path, computed ahead in blocks (spec 6.1):

    true body rate -> mounting, scale factor, misalignment -> + the sensing element's
    noise -> low-pass for BW (data_high_bw: none) -> + offset (6.9) -> x sensitivity(RANGE)
    -> round, saturate to int16 -> the bytes of the RATE registers.

The noise enters before the filter in the physical mode and after it in the paper mode
(``noise.sensor_noise.SensorNoise``: where each term enters, docs/noise-engine.md).

A block is thrown away from the current sample on when the configuration changes
(``invalidate``); the filter state and the noise realisation carry over, so the samples do
not depend on how far ahead a block was computed.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import Any

import numpy as np

from bmg160_emu.device import spec_choices as choice
from bmg160_emu.noise.lowpass import LowPass
from bmg160_emu.noise.sensor_noise import SensorNoise

SPAN = 1024  # samples computed ahead, in pieces of 1, 2, 4, ... as they are used
MAX_SPAN = 65536  # when catching up a long gap


class Block:
    """The data path for samples k0 .. k0 + n - 1: (n, 3) arrays (``OneSample``: lists)."""

    __slots__ = ("body", "dps_f", "dps_u", "end", "high_bw", "k0", "n", "rate_bytes",
                 "samples", "selected", "sensitivity", "unselected", "x", "y", "zi0")
    k0: int
    n: int
    end: int
    body: np.ndarray  # true body rate, deg/s
    x: np.ndarray  # sensor-frame rate before the filter
    y: Any  # filtered
    zi0: np.ndarray  # filter state before the first sample
    dps_f: Any  # filtered + noise + offset, deg/s
    dps_u: Any  # unfiltered + noise + offset, deg/s
    sensitivity: float  # LSB per deg/s the counts are scaled with
    high_bw: bool  # data_high_bw: the unfiltered counts are the ones read
    selected: Any  # the counts read (counts_u with high_bw, else counts_f)
    unselected: Any  # the other counts, computed when asked for (the interrupt engines)
    rate_bytes: bytes  # the selected counts, 6 bytes per sample
    samples: list[bytes] | None  # rate_bytes sample by sample, once asked for (cut_samples)

    def cut_samples(self) -> list[bytes]:
        """``rate_bytes`` as one 6-byte string per sample, cut once (numpy's void view: 22 ns a
        sample against a 60 ns slice at each of a polling driver's advances)."""
        samples = self.samples = np.frombuffer(self.rate_bytes, dtype="V6").tolist()
        return samples

    @property
    def counts_f(self) -> Any:
        """Filtered counts (n, 3) int16."""
        return self.selected if not self.high_bw else self._unselected()

    @property
    def counts_u(self) -> Any:
        """Unfiltered counts (n, 3) int16."""
        return self.selected if self.high_bw else self._unselected()

    def _unselected(self) -> Any:
        counts = self.unselected
        if counts is None:  # (not computed with the block: only the engines ask for them)
            dps = self.dps_f if self.high_bw else self.dps_u
            counts = self.unselected = to_counts(dps, self.sensitivity)
        return counts

    def frames(self, lo: int, hi: int, axis: slice, tag: bytes) -> list[bytes]:
        """FIFO frames of samples lo .. hi - 1: the selected axes, then the tag bytes."""
        rb, start, stop = self.rate_bytes, axis.start, axis.stop
        return [rb[i + start:i + stop] + tag for i in range(6 * (lo - self.k0), 6 * (hi - self.k0), 6)]


class OneSample(Block):
    """A one-sample block (``DataPath.build``): its rows are lists of one row, and its counts
    are computed when asked for (``counts_of``; a loop's sample hooks replace them)."""

    __slots__ = ()

    def __init__(self, sensitivity: float, high_bw: bool) -> None:
        self.sensitivity, self.high_bw, self.samples = sensitivity, high_bw, None

    @property
    def counts_f(self) -> list[tuple[int, int, int]]:
        return [counts_of(self.dps_f[0], self.sensitivity)[0]]

    @property
    def counts_u(self) -> list[tuple[int, int, int]]:
        return [counts_of(self.dps_u[0], self.sensitivity)[0]]

    @property
    def rate_bytes(self) -> bytes:  # type: ignore[override]
        return counts_of(self.dps_u[0] if self.high_bw else self.dps_f[0], self.sensitivity)[1]

    def cut_samples(self) -> list[bytes]:
        samples = self.samples = [self.rate_bytes]
        return samples


def next_piece(block: Block | None, k: int, want: int, span: tuple[int, int],
               hint: int) -> tuple[bool, int, tuple[int, int]]:
    """(starts a span, samples to compute, the span's (start, end)) for the piece from
    sample k, at least ``want`` samples, after ``block`` (the last piece, None after a
    change); ``hint``: how many samples of the last span were used before that change.

    A span (SPAN samples, or the gap being caught up) is computed in pieces: after a change,
    first as many samples as the last span used, then doubling. So a closed loop changing the
    true rate after each sample recomputes one sample, not a span, while a chip left alone
    computes whole spans. The filter runs on across the pieces of a span (re-referenced only
    where a span starts). In a closed loop the one-sample pieces are bit for bit the first
    samples of the blocks they replace; after a change, the pieces' rates agree with one
    block's to rounding (~1e-15 of the rate: the low-pass's sub-block products round by where
    a block starts, lowpass.py), so the counts agree but where a rate lies that close to a
    rounding boundary (as lowpass.py says of its own blocks)."""
    natural = block is not None and k == block.end == span[1]
    if block is None or k != block.end or k >= span[1]:
        size = SPAN if want <= SPAN else min(want, MAX_SPAN)
        return True, size if natural else min(max(want, hint), size), (k, k + size)
    return False, min(max(2 * block.n, want), span[1] - k), span


def to_counts(dps: np.ndarray, sensitivity: float) -> np.ndarray:
    """deg/s to RATE counts: x LSB/(deg/s), round half to even, saturate to int16 (6.1).
    (minimum/maximum: the values of np.clip for finite input, at a fraction of its cost
    on the one-sample blocks of a closed loop.)"""
    return np.minimum(np.maximum(np.rint(dps * sensitivity), -32768.0), 32767.0).astype(np.int16)


def to_bytes(counts: np.ndarray) -> bytes:
    """The RATE register bytes of int16 counts: LSB first (4.2)."""
    return counts.tobytes() if _NATIVE_LITTLE else counts.astype("<i2").tobytes()


_NATIVE_LITTLE = np.little_endian
_INT16_XYZ = struct.Struct("<3h")


def _nan_count() -> int:
    return int(to_counts(np.array([np.nan]), 1.0)[0])


def counts_of(dps: list[float], sensitivity: float) -> tuple[tuple[int, int, int], bytes]:
    """``to_counts`` and ``to_bytes`` of one sample in Python floats: the same product,
    round half to even (``round``, as np.rint) and saturation; beyond int16 (an infinite
    product included) the limit, as np.clip's; NaN what numpy's cast makes of it."""
    x, y, z = dps
    x *= sensitivity
    y *= sensitivity
    z *= sensitivity
    if -32768.0 < x < 32767.0 and -32768.0 < y < 32767.0 and -32768.0 < z < 32767.0:
        x, y, z = round(x), round(y), round(z)  # (within range, not NaN: the common case)
        return (x, y, z), _INT16_XYZ.pack(x, y, z)
    c = []
    for v in dps:
        v *= sensitivity
        if v >= 32767.0:
            c.append(32767)
        elif v <= -32768.0:
            c.append(-32768)
        else:
            try:
                c.append(round(v))
            except ValueError:  # NaN
                c.append(_nan_count())
    x, y, z = c
    return (x, y, z), _INT16_XYZ.pack(x, y, z)


def run_sample_hooks(chip: Any, t_s: float, rate_dps: np.ndarray) -> np.ndarray | None:
    """The chip's sample hooks in order on one sample's rate (deg/s, before scaling); None
    when one drops it (a lost sample)."""
    rate = np.array(rate_dps, dtype=np.float64)
    for hook in list(chip.sample_hooks):
        result = hook(chip, t_s, rate)
        if result is None:
            return None
        if result.__class__ is np.ndarray and result.shape == (3,) and result.dtype == _F8:
            rate = result  # what asarray and reshape would give: the array itself (a loop's
            continue  # fault hook returns its argument; 1 us a sample less)
        rate = np.asarray(result, dtype=np.float64)
        if rate.size != 3:
            raise ValueError(f"sample hook {hook!r} must return 3 numbers in deg/s or "
                             f"None, got {rate.size} at t = {t_s:g} s")
        rate = rate.reshape(3)
    return rate


_F8 = np.dtype(np.float64)


def sensitivity_table(sensitivity: str | Sequence[float]) -> tuple[float, ...]:
    """LSB/(deg/s) of RANGE codes 0..4: a table name of spec_choices or 5 figures (5.1)."""
    if isinstance(sensitivity, str):
        try:
            return choice.SENSITIVITY_TABLES[sensitivity]
        except KeyError:
            raise ValueError(f"sensitivity must be one of {sorted(choice.SENSITIVITY_TABLES)}"
                             f" or 5 numbers, not {sensitivity!r}") from None
    table = tuple(float(s) for s in sensitivity)
    if len(table) != 5 or not all(math.isfinite(s) and s > 0 for s in table):
        raise ValueError("sensitivity table needs 5 positive LSB/(deg/s) figures")
    return table


# Largest scale-factor error and cross-axis coupling taken (fractions): a unit whose
# sensitivity is off by 100 % or whose axes couple 1:1 is no gyroscope (the data sheet's are
# 1 %, BST-BMG160-DS000 table 1), and the bound keeps every product of the path finite.
MAX_ERROR_FRACTION = 1.0


def _as_matrix(value: Any, name: str) -> np.ndarray:
    m = np.asarray(value, dtype=float)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise ValueError(f"{name} must be a finite 3x3 matrix")
    return m


def body_to_sensor(mounting: Any, scale_factor: Any, misalignment: Any) -> np.ndarray | None:
    """The matrix from body rate to sensor-frame rate, None for the identity."""
    if mounting is None and scale_factor is None and misalignment is None:
        return None
    m = np.eye(3)
    if mounting is not None:
        r = _as_matrix(mounting, "mounting")
        if not np.allclose(r @ r.T, np.eye(3), atol=1e-9):
            raise ValueError("mounting must be a rotation matrix (orthonormal)")
        m = r
    if scale_factor is not None:
        sf = np.asarray(scale_factor, dtype=float)
        if sf.shape != (3,) or not np.all(np.abs(sf) <= MAX_ERROR_FRACTION):
            raise ValueError(f"scale_factor must be 3 fractional errors within "
                             f"+-{MAX_ERROR_FRACTION:g} (finite)")
        m = np.diag(1.0 + sf) @ m
    if misalignment is not None:
        mis = _as_matrix(misalignment, "misalignment")
        off = mis - np.diag(np.diag(mis))
        if not np.all(np.abs(off) <= MAX_ERROR_FRACTION):
            raise ValueError(f"misalignment couplings must be within +-{MAX_ERROR_FRACTION:g}")
        m = (np.eye(3) + off) @ m
    return m


def noise_generator(profile: Any, mode: str, seed: int | None, address: int) -> Any:
    """The chip's noise engine; ``seed`` with the I2C address, so two chips sharing a master
    seed have independent noise."""
    from bmg160_emu.noise import NoiseGenerator

    if seed is not None:
        seed = int(np.random.SeedSequence([int(seed), address]).generate_state(1, np.uint64)[0])
    return NoiseGenerator(profile=profile, rate_hz=2000.0, seed=seed, mode=mode)


class DataPath:
    """Transform, filter and noise of one chip; builds blocks, carries state across them."""

    def __init__(self, transform: np.ndarray | None, noise_generator: Any,
                 budget: Any = None) -> None:
        self.transform = transform
        self.budget = budget  # environment.ErrorBudget: the unit's errors, before the filter
        self.noise = SensorNoise(noise_generator)
        self.odr_hz: int | None = None  # no filter before the first set_filter
        self.filter: LowPass | None = None
        self.restart_filter = True  # the next block starts the filter at rest at its input
        self.last_y: Any = None  # filter output of the last sample produced (3 numbers)
        self._errors_seen: Any = None  # the budget's SensorErrors when last asked if active
        self._errors_active = False

    def set_filter(self, code: int, used_end: int) -> None:
        """ODR and filter of BW code ``code`` (0..7); the noise from sample ``used_end`` on is
        redrawn at the new ODR and through the new filter, and the true rate gets a filter of
        the same design: one call into the noise layer (SensorNoise.configure_code), which
        holds the code's figures (noise.bandwidths)."""
        self.odr_hz, self.filter = self.noise.configure_code(code, used_end)

    def change_bandwidth(self, code: int, used_end: int) -> None:
        """A new BW code while running: the new filter continues from the last output."""
        self.set_filter(code, used_end)
        if self.last_y is not None and not self.restart_filter:
            assert self.filter is not None
            self.filter.restart(self.last_y)
        else:
            self.restart_filter = True

    def invalidate(self, block: Block | None, k: int) -> None:
        """Forget ``block`` after sample ``k``: the filter state is the one after ``k``."""
        if block is None:
            return
        assert self.filter is not None
        j = k - block.k0
        if j >= block.n - 1:  # all used: the state after the block is the one after k
            self.last_y = block.y[block.n - 1].copy()  # an array's row or a list
        elif j >= 0:
            _, self.filter.state = self.filter.run(block.x[: j + 1], block.zi0)
            self.last_y = block.y[j].copy()
        else:
            self.filter.state = block.zi0

    def build(self, k0: int, body: np.ndarray, offset_dps: np.ndarray, sensitivity: float,
              high_bw: bool, constant_rate: bool, *, first: bool = True) -> Block:
        """The block of samples k0 .. k0 + len(body) - 1 for true body rates ``body``;
        ``first=False`` continues the previous block's span (no re-referencing)."""
        n = len(body)
        x = body if self.transform is None else body @ self.transform.T
        budget = self.budget
        if budget is not None:
            errors = budget.errors
            if errors is not self._errors_seen:  # SensorErrors is frozen: ask once per set
                self._errors_seen, self._errors_active = errors, budget.active
            if self._errors_active:
                x = budget.apply(x, k0, sensitivity)
                constant_rate = constant_rate and not budget.time_varying
        filt = self.filter
        assert filt is not None
        if self.restart_filter:
            filt.restart(x[0])
            self.restart_filter = False
        elif constant_rate and first:
            filt.rebase_if_settled(x[0])
        b = OneSample(sensitivity, high_bw) if n == 1 else Block()
        b.k0, b.n, b.end = k0, n, k0 + n
        b.body, b.x, b.zi0 = body, x, filt.state
        if isinstance(b, OneSample):
            return self._finish_one(b, x[0].tolist(), offset_dps)
        b.y, filt.state = filt.run(x)
        raw, out = self.noise.take(k0, n)
        offset = np.count_nonzero(offset_dps) != 0  # (offset_dps.any(): 5x its cost)
        if offset:
            raw, out = raw + offset_dps, out + offset_dps
        if self.noise.generator is None and not offset:
            b.dps_f, b.dps_u = b.y, x
        else:
            b.dps_f, b.dps_u = b.y + out, x + raw
        b.sensitivity, b.high_bw, b.unselected, b.samples = sensitivity, high_bw, None, None
        b.selected = to_counts(b.dps_u if high_bw else b.dps_f, sensitivity)
        b.rate_bytes = to_bytes(b.selected)
        return b

    def _finish_one(self, b: OneSample, x: list[float], offset_dps: np.ndarray) -> Block:
        """A one-sample block (a closed loop's piece) in Python floats: the same operations
        as for n samples in the same order, so bit for bit the same values."""
        assert self.filter is not None
        y = self.filter.step(x)
        offset = offset_dps.tolist()
        if self.noise.generator is None and not any(offset):
            dps_f, dps_u = y, x
        else:
            raw_rows, out_rows = self.noise.take(b.k0, 1)
            raw, out = raw_rows[0].tolist(), out_rows[0].tolist()
            if any(offset):
                raw = [a + o for a, o in zip(raw, offset)]
                out = [a + o for a, o in zip(out, offset)]
            dps_f = [a + e for a, e in zip(y, out)]
            dps_u = [a + e for a, e in zip(x, raw)]
        b.y, b.dps_f, b.dps_u = [y], [dps_f], [dps_u]
        return b
