"""The chip's data path, computed ahead in blocks (spec 6.1):

    true body rate -> mounting, scale factor, misalignment -> + the sensing element's
    noise -> low-pass for BW (data_high_bw: none) -> + offset (6.9) -> x sensitivity(RANGE)
    -> round, saturate to int16 -> the bytes of the RATE registers.

The noise enters before the filter in the physical mode and after it in the paper mode
(``SensorNoise``: where each term enters, docs/noise-engine.md).

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
from bmg160_emu.device.lowpass import LowPass

NOISE_CHUNK = 2048  # noise computed in chunks of this many samples (a multiple of the
# filter's 1024-sample pieces, lowpass.py), each with its filter state kept
PIECE = 16 * NOISE_CHUNK  # samples generated and filtered at once within a draw: the three
# 768 kB arrays of a piece stay in the cache between the generator and the filter
SPAN = 1024  # samples computed ahead, in pieces of 1, 2, 4, ... as they are used
MAX_SPAN = 65536  # when catching up a long gap


class Block:
    """The data path for samples k0 .. k0 + n - 1: (n, 3) arrays (``OneSample``: lists)."""

    __slots__ = ("body", "counts_f", "counts_u", "dps_f", "dps_u", "end", "k0", "n",
                 "rate_bytes", "x", "y", "zi0")
    k0: int
    n: int
    end: int
    body: np.ndarray  # true body rate, deg/s
    x: np.ndarray  # sensor-frame rate before the filter
    y: Any  # filtered
    zi0: np.ndarray  # filter state before the first sample
    dps_f: Any  # filtered + noise + offset, deg/s
    dps_u: Any  # unfiltered + noise + offset, deg/s
    counts_f: Any
    counts_u: Any
    rate_bytes: bytes  # the selected counts, 6 bytes per sample

    def frames(self, lo: int, hi: int, axis: slice, tag: bytes) -> list[bytes]:
        """FIFO frames of samples lo .. hi - 1: the selected axes, then the tag bytes."""
        rb, start, stop = self.rate_bytes, axis.start, axis.stop
        return [rb[i + start:i + stop] + tag for i in range(6 * (lo - self.k0), 6 * (hi - self.k0), 6)]


class OneSample(Block):
    """A one-sample block (``DataPath.build``): its rows are lists of one row, and its counts
    are computed when asked for (``counts_of``; a loop's sample hooks replace them)."""

    __slots__ = ("high_bw", "sensitivity")

    def __init__(self, sensitivity: float, high_bw: bool) -> None:
        self.sensitivity, self.high_bw = sensitivity, high_bw

    @property
    def counts_f(self) -> list[tuple[int, int, int]]:
        return [counts_of(self.dps_f[0], self.sensitivity)[0]]

    @property
    def counts_u(self) -> list[tuple[int, int, int]]:
        return [counts_of(self.dps_u[0], self.sensitivity)[0]]

    @property
    def rate_bytes(self) -> bytes:  # type: ignore[override]
        return counts_of(self.dps_u[0] if self.high_bw else self.dps_f[0], self.sensitivity)[1]


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
        rate = np.asarray(result, dtype=np.float64)
        if rate.size != 3:
            raise ValueError(f"sample hook {hook!r} must return 3 numbers in deg/s or "
                             f"None, got {rate.size} at t = {t_s:g} s")
        rate = rate.reshape(3)
    return rate


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


class SensorNoise:
    """The sensing element's noise by sample index: raw, and as the chip's output carries it.

    Where the noise enters (docs/noise-engine.md): in ``physical`` mode the noise is made in
    the sensing element, before the chip's digital low-pass, so the filtered output carries
    it through the filter of the BW code and the unfiltered (data_high_bw) output raw; only
    the profile's Q term (an output's quantization, IEEE 952) is added after the filter. In
    ``paper`` mode the paper's recursion is the chip's output (output-referred, its Table 3):
    both outputs carry it unfiltered. The true rate has its own filter (``DataPath``); the
    filter is linear, so the two filters together are the chip's one filter of rate + noise.

    The filter's start: each configuration (ODR and filter) starts with the filter settled
    on ``settle_samples`` samples of fresh noise drawn for the purpose, so the noise is
    stationary from its first sample (a powered sensor, or a chip whose filter has run
    since its BW was set); the realisation moves on by those samples.

    Chunk invariance: noise is computed in chunks of NOISE_CHUNK samples counted from the
    start of the configuration, each filtered from the state the previous one left, and
    each draw keeps the generator's checkpoint, so sample k does not depend on how far
    ahead the data path had computed; a new configuration at sample k goes back to the
    chunk holding k, draws to k again and continues there (``configure``). ``generate``
    (the command and ``profile_noise``) uses the same class, so a file of noise and a
    chip's registers hold the same model."""

    def __init__(self, generator: Any, filtered: bool | None = None,
                 sequential: bool = False) -> None:
        self.generator = generator
        # the filter's kernel: the numpy block filter of lowpass.py in chunks (the chip: no
        # scipy on its import path), or scipy's sequential lfilter over each draw (generate:
        # a recursion gives the same bits however the record is cut, at a fifth of the cost)
        self.sequential = sequential
        # paper mode: output-referred (no filter on the noise)
        self.filtered = (generator is not None and generator.mode == "physical"
                         if filtered is None else bool(filtered))
        self.filter: LowPass | None = None
        self.config: tuple[Any, ...] | None = None
        self.seg = 0  # sample where the current configuration starts
        self.k0 = 0  # first sample held
        self.end = 0  # one past the last sample drawn
        self.raw = np.zeros((0, 3))  # what the unfiltered output adds
        self.out = self.raw  # what the filtered output adds (raw in paper mode)
        self.draws: list[tuple[int, Any]] = []  # (first sample, generator checkpoint)
        self.state: np.ndarray | None = None  # filter state at self.end
        self.notes: list[str] = []  # what configure said (a profile filter not applied)

    def configure(self, odr_hz: float, bandwidth_hz: float | None, used_end: int,
                  order: int = choice.LOWPASS_ORDER) -> None:
        """The chip's ODR and filter from sample ``used_end`` on (None: no filter); noise
        drawn for later samples is redrawn. Nothing changes if both are as they were."""
        gen = self.generator
        config = ((float(odr_hz), bandwidth_hz, int(order)) if self.filtered
                  else (float(odr_hz),))
        if gen is None or config == self.config:
            self.config = config
            return
        if self.config is not None:
            self._rewind(used_end)
        if gen.rate_hz != float(odr_hz):
            gen.set_rate(float(odr_hz))
        self.config = config
        self.seg = self.end = used_end
        self.draws = []
        self.filter = None
        if self.filtered and bandwidth_hz is not None:
            self.filter = LowPass(float(odr_hz), float(bandwidth_hz), int(order))
            settle, _ = gen.generate_referred(self.filter.design.settle_samples())
            self.filter.settle_on(settle)  # the slow terms settled, the white ones decayed
            self.state = self.filter.state
            self._note_filter(odr_hz, bandwidth_hz, order)

    def take(self, k0: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(unfiltered, filtered) noise of samples k0 .. k0 + n - 1, deg/s; samples before
        k0 are forgotten."""
        if self.generator is None:
            zeros = np.zeros((n, 3))
            return zeros, zeros
        if k0 < self.k0:
            raise RuntimeError(f"noise of sample {k0} was forgotten (held from {self.k0})")
        if k0 > self.k0:
            self._forget(min(k0, self.end))
        if k0 + n > self.end:
            self._draw(k0 + n)
            if k0 > self.k0:  # a gap: samples drawn and never used
                self._forget(k0)
        return self.raw[:n], self.out[:n]

    def _draw(self, end: int) -> None:
        """Whole chunks from self.end until ``end`` is covered (one generator checkpoint),
        generated and filtered in pieces of PIECE samples, each while it is in the cache
        (the generator is chunk invariant: the same samples as one call)."""
        gen = self.generator
        total = -(-(end - self.end) // NOISE_CHUNK) * NOISE_CHUNK
        self.draws.append((self.end, gen.checkpoint()))
        flt = self.filter
        held = self.end - self.k0
        if self.sequential and held == 0:  # generate: one call, one pass of the recursion
            pre, post = gen.generate_referred(total)
            self.raw = pre if post is None else pre + post
            self.out = self.raw
            if flt is not None:
                from scipy.signal import lfilter

                self.out, self.state = lfilter(flt.b, flt.a, pre, axis=0, zi=self.state)
                if post is not None:
                    self.out += post
            self.end += total
            return
        raw = np.empty((held + total, 3))
        raw[:held] = self.raw[:held]
        out = raw if flt is None else np.empty((held + total, 3))
        if flt is not None:
            out[:held] = self.out[:held]
        for start in range(0, total, PIECE):
            m = min(PIECE, total - start)
            at = held + start
            pre, post = gen.generate_referred(m)
            raw[at:at + m] = pre if post is None else pre + post
            if flt is None:
                continue
            assert self.state is not None  # set when the filter was configured
            if self.sequential:
                from scipy.signal import lfilter

                out[at:at + m], self.state = lfilter(flt.b, flt.a, pre, axis=0, zi=self.state)
            else:
                out[at:at + m], self.state = flt.run_pieces(pre, self.state, NOISE_CHUNK)
            if post is not None:
                out[at:at + m] += post
        self.raw, self.out = raw, out
        self.end += total

    def _forget(self, k0: int) -> None:
        """Drop samples before k0, and the checkpoints no rewind to k0 or later needs."""
        cut = k0 - self.k0
        same = self.out is self.raw
        self.raw = self.raw[cut:]
        self.out = self.raw if same else self.out[cut:]
        self.k0 = k0
        draws = self.draws
        first = 0
        while first + 1 < len(draws) and draws[first + 1][0] <= k0:
            first += 1
        del draws[:first]

    def _rewind(self, used_end: int) -> None:
        """The generator back at sample ``used_end``; later samples dropped. (The filter's
        state there is not needed: a new configuration starts its filter settled.)"""
        if used_end > self.end:
            self._draw(used_end)
        if used_end < self.end:
            draw = max((d for d in self.draws if d[0] <= used_end), default=None,
                       key=lambda d: d[0])
            if draw is None:
                raise RuntimeError(f"noise of sample {used_end} was forgotten")
            self.generator.restore(draw[1])
            if used_end > draw[0]:
                self.generator.generate(used_end - draw[0])
        keep = max(used_end - self.k0, 0)
        same = self.out is self.raw
        self.raw = self.raw[:keep]
        self.out = self.raw if same else self.out[:keep]
        self.end = used_end

    def _note_filter(self, odr_hz: float, bandwidth_hz: float, order: int) -> None:
        """Say so when the profile names a filter of its own that is not this one: the chip
        filters its noise with its BW setting, never twice (docs/noise-engine.md)."""
        profile = getattr(self.generator, "profile", None)
        stage = getattr(profile, "output", None)
        if stage is None or not stage.has_filter:
            return
        if stage.bw_code is not None:
            same = choice.BANDWIDTHS[stage.bw_code] == (odr_hz, bandwidth_hz) and (
                order == choice.LOWPASS_ORDER)
        else:
            same = order == stage.order and abs(stage.corner_hz / bandwidth_hz - 1) < 0.02
        if same:
            return
        name = getattr(profile, "name", "")
        note = (f"noise profile {name!r} was identified through {stage.filter_text()}; "
                f"the chip filters its noise with its own BW setting ({bandwidth_hz:g} Hz at "
                f"{odr_hz:g} Hz ODR) instead")
        if note not in self.notes:
            self.notes.append(note)
            import logging  # only when there is a note: not on a chip's import path

            logging.getLogger(__name__).info(note)


class ProfileNoise:
    """A profile's noise as ``generate`` writes it: the sensing element's noise through the
    profile's own output filter (``[output]``: order and corner, or a BW code) or a BW
    code's filter, then rounded to the profile's LSB, by the same ``SensorNoise`` a chip
    uses. ``generate(n)``: the next n samples (n, 3) in deg/s."""

    def __init__(self, generator: Any, bandwidth_hz: float | None, order: int,
                 lsb_dps: float | None = None) -> None:
        self.generator = generator
        self.lsb_dps = lsb_dps
        self.bandwidth_hz = bandwidth_hz
        self.order = order
        self._noise = SensorNoise(generator, filtered=generator.mode == "physical",
                                  sequential=True)
        self._noise.configure(generator.rate_hz, bandwidth_hz, 0, order)
        self._k = 0

    @property
    def rate_hz(self) -> float:
        return float(self.generator.rate_hz)

    @property
    def profile(self) -> Any:
        return self.generator.profile

    @property
    def mode(self) -> str:
        return str(self.generator.mode)

    def describe(self) -> str:
        """The output stage in one word for file headers: 'none', or the filter and LSB."""
        parts = []
        if self.bandwidth_hz is not None and self.mode == "physical":
            parts.append(f"butterworth{self.order}@{self.bandwidth_hz:g}Hz")
        if self.lsb_dps:
            parts.append(f"lsb{self.lsb_dps:.6g}dps")
        return ",".join(parts) or "none"

    def generate(self, n: int) -> np.ndarray:
        _, out = self._noise.take(self._k, n)
        self._k += n
        if self.lsb_dps:
            return np.rint(out / self.lsb_dps) * self.lsb_dps
        return out  # rows handed out once: the buffer never writes them nor uses them again


def profile_noise(profile: Any, rate_hz: float | None = None, seed: Any = None,
                  mode: str = "physical", bandwidth_code: int | None = None,
                  use_output: bool = True) -> ProfileNoise:
    """The noise ``generate`` writes for a profile: at ``rate_hz`` (default: the BW code's
    ODR, else the rate the profile's output stage was found at, else 200 Hz) through the BW
    code's filter when one is given, else the profile's own output filter (``use_output``),
    rounded to its LSB; physical mode only filters (paper mode is output-referred).
    ValueError on a rate the code does not have."""
    from bmg160_emu.noise import NoiseGenerator, load_profile

    profile = load_profile(profile)
    stage = profile.output if use_output else None
    code = bandwidth_code
    if code is None and stage is not None and stage.bw_code is not None:
        code = stage.bw_code
    bandwidth: float | None = None
    order = choice.LOWPASS_ORDER
    if code is not None:
        if isinstance(code, bool) or code not in choice.BANDWIDTHS:
            codes = ", ".join(f"{c} ({o} Hz ODR, {b:g} Hz)" for c, (o, b) in choice.BANDWIDTHS.items())
            raise ValueError(f"unknown BW code {code!r}: use one of {codes}")
        odr, bandwidth = choice.BANDWIDTHS[code]
        if rate_hz is not None and float(rate_hz) != odr:
            raise ValueError(f"rate {float(rate_hz):g} Hz disagrees with BW code {code} "
                             f"(ODR {odr} Hz): give one of them")
        rate_hz = float(odr)
    elif stage is not None and stage.corner_hz is not None:
        bandwidth, order = stage.corner_hz, int(stage.order or order)
    if rate_hz is None and stage is not None and stage.rate_hz is not None:
        rate_hz = stage.rate_hz
    generator = NoiseGenerator(profile, rate_hz=200.0 if rate_hz is None else rate_hz,
                               seed=seed, mode=mode)
    lsb = stage.lsb_dps if stage is not None else None
    return ProfileNoise(generator, bandwidth, order, lsb)


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

    def set_filter(self, odr_hz: int, bandwidth_hz: float, used_end: int) -> None:
        """Filter for a BW code; the noise from sample ``used_end`` on is redrawn at the new
        ODR and through the new filter (SensorNoise.configure)."""
        self.odr_hz = odr_hz
        self.filter = LowPass(odr_hz, bandwidth_hz)
        self.noise.configure(odr_hz, bandwidth_hz, used_end)

    def change_bandwidth(self, odr_hz: int, bandwidth_hz: float, used_end: int) -> None:
        """A new BW code while running: the new filter continues from the last output."""
        self.set_filter(odr_hz, bandwidth_hz, used_end)
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
        if offset_dps.any():
            raw, out = raw + offset_dps, out + offset_dps
        if self.noise.generator is None and not offset_dps.any():
            b.dps_f, b.dps_u = b.y, x
        else:
            b.dps_f, b.dps_u = b.y + out, x + raw
        b.counts_f = to_counts(b.dps_f, sensitivity)
        b.counts_u = to_counts(b.dps_u, sensitivity)
        sel = b.counts_u if high_bw else b.counts_f
        b.rate_bytes = to_bytes(sel)
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
