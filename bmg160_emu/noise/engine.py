"""The gyroscope noise generator: per-axis N, B, T, K (+ Q, R) streams, seeded, chunk invariant.

Interface (used by the device model, see docs/architecture.md):

    gen = NoiseGenerator(profile="paper", rate_hz=200.0, seed=7, mode="physical")
    gen.generate(n) -> ndarray (n, 3) float64, deg/s, constant bias included
    gen.set_rate(rate_hz)   # continue the same realisation at another output data rate

Why it is chunk invariant: every term of every axis draws from its own numpy Generator
(children of one SeedSequence), so sample k always consumes the k-th normal of each stream;
the Gauss-Markov recursions and the random walk (gauss_markov.py: block-wise scaled
cumulative sums on super-blocks counted from the start or the last rate change, numpy only,
no scipy on the chip's import path) carry their state exactly, so the floating-point
operations per sample do not depend on how the stream is cut.

Streams per axis: white, gm (the first Gauss-Markov term), rw, quant, then gm1, gm2, ...
for further terms (spawned after the first four, so a one-term profile draws exactly the
normals it drew before multi-term profiles existed), then one stream for the phases of the
sinusoidal terms (drawn once, uniform in [0, 2 pi)).

Where each term is referred: everything but Q is the sensing element's noise, which the
chip's low-pass filters (``generate_referred`` hands it apart); Q, the IEEE 952 angle
quantization of an output, is output-referred (docs/noise-engine.md, "Where each term enters").

Small requests are served from a short buffer of computed samples (a few microseconds per
call); the buffer keeps its normals so that set_rate() can recompute the unserved part at the
new rate from the exact state of the last served sample.
"""

from __future__ import annotations

import operator
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.noise.discretization import (
    SUPPORTED_RATES_HZ,
    AxisCoefficients,
    axis_coefficients,
    check_mode,
    check_rate,
)
from bmg160_emu.noise.gauss_markov import Pole, ResonancePole
from bmg160_emu.noise.profile import AxisNoise, Profile, load_profile

__all__ = ["NoiseGenerator", "load_profile"]

_BUFFER_SAMPLES = 1024  # samples computed ahead for small requests
_BLOCK_SAMPLES = 1 << 15  # block length of large requests (keeps the scratch arrays in cache)
_STREAMS = ("white", "gm", "rw", "quant")


class _AxisStream:
    """One axis: its random streams, its coefficients and the state after its last sample."""

    def __init__(self, axis: AxisNoise, seed_seq: np.random.SeedSequence, mode: str) -> None:
        self.axis = axis
        terms = axis.gauss_markov_terms
        children = seed_seq.spawn(len(_STREAMS))
        if len(terms) > 1:
            children += seed_seq.spawn(len(terms) - 1)
        names = list(_STREAMS) + [f"gm{i}" for i in range(1, len(terms))]
        if axis.sine:  # spawned last: the other streams are those of a profile without it
            children += seed_seq.spawn(1)
            names.append("sine")
        if axis.resonators:  # after the sines: a profile without bands draws what it drew before
            children += seed_seq.spawn(len(axis.resonators))
            names += [f"band{i}" for i in range(len(axis.resonators))]
        self.rng = {
            name: np.random.Generator(np.random.PCG64(s)) for name, s in zip(names, children)
        }
        # each sinusoid: A sin(2 pi f t + phase), phases fixed by the seed
        phases = (self.rng["sine"].uniform(0.0, 2.0 * np.pi, len(axis.sine)).tolist()
                  if axis.sine else [])
        self.sines = [(A, 2.0 * np.pi * f, float(p)) for (A, f), p in zip(axis.sine, phases)]
        self.gm_names = (["gm"] + names[len(_STREAMS):]) if terms else []
        self.uses = {
            "white": axis.N > 0 if mode == "physical" else True,
            "gm": bool(terms),
            "rw": axis.K > 0,
            "quant": axis.Q > 0,
        }
        self._drawn = [name for name in ("white", "quant") if self.uses[name]]
        # each Gauss-Markov term draws its own normals (gauss_markov.Pole), starting in its
        # stationary distribution
        self.poles = [Pole(self.rng[name], B) for name, (B, _) in zip(self.gm_names, terms)]
        # the random walk is the same recursion with a = 1, starting at 0
        self.walk = Pole(self.rng["rw"], None) if self.uses["rw"] else None
        # each resonator of a band: a complex Gauss-Markov term (gauss_markov.ResonancePole)
        self.resonators = [ResonancePole(self.rng[f"band{i}"])
                           for i in range(len(axis.resonators))]
        self._all = (self.poles + ([self.walk] if self.walk is not None else [])
                     + list(self.resonators))
        self.quant_prev = float(self.rng["quant"].standard_normal()) if self.uses["quant"] else 0.0
        self.coef: AxisCoefficients | None = None

    def set_coefficients(self, coef: AxisCoefficients) -> None:
        """New rate: each Gauss-Markov term continues from its last value."""
        self.coef = coef
        for pole, pc in zip(self.poles, coef.poles):
            pole.restart(pc)
        if self.walk is not None:
            assert coef.walk is not None
            self.walk.restart(coef.walk)
        for resonator, rc in zip(self.resonators, coef.bands):
            resonator.restart_resonance(rc)

    def draw(self, n: int) -> dict[str, np.ndarray | None]:
        out: dict[str, np.ndarray | None] = {"white": None, "quant": None}
        for name in self._drawn:
            out[name] = self.rng[name].standard_normal(n)
        return out

    def state(self) -> tuple[Any, ...]:
        return (tuple(p.state() for p in self._all), self.quant_prev)

    def compute(
        self, normals: dict[str, np.ndarray | None], t: np.ndarray | None, out: np.ndarray,
        post: np.ndarray | None = None, consume: bool = False,
    ) -> None:
        """Write this axis's samples into out (a possibly strided view); advance the state
        (the Gauss-Markov terms and the walk rewind from their saved state on a rate change).
        With ``post``, the output-referred term (Q) goes there instead of into out;
        ``consume``: the normals are not kept (their array is worked in).
        """
        c = self.coef
        assert c is not None
        n = out.shape[0]
        white = normals["white"]
        if white is not None and consume:  # normals not kept: scaled where they lie
            acc = white
            acc *= c.white_std
        elif white is not None:
            acc = np.empty(n)
            np.multiply(white, c.white_std, out=acc)
        else:
            acc = np.zeros(n)
        for pole in self._all:
            acc += pole.take(n)
        wq = normals["quant"]
        if wq is not None:
            diff = np.empty(n)
            diff[0] = wq[0] - self.quant_prev
            np.subtract(wq[1:], wq[:-1], out=diff[1:])
            diff *= c.quant_scale
            if post is None:
                acc += diff
            else:
                post[:] = diff
            self.quant_prev = float(wq[-1])
        elif post is not None:
            post[:] = 0.0
        if t is not None:
            if c.ramp_slope > 0:
                acc += c.ramp_slope * t
            for amplitude, omega, phase in self.sines:
                acc += amplitude * np.sin(omega * t + phase)
        np.add(acc, c.bias, out=out)


class NoiseGenerator:
    """Seeded, chunk-invariant noise of the three gyroscope axes in deg/s (bias included).

    profile: a built-in name ("paper", "datasheet"), a TOML path, a Profile or a mapping.
    rate_hz: output data rate, one of the BMG160's 100, 200, 400, 1000, 2000 Hz.
    seed: int, None (fresh entropy) or numpy SeedSequence.
    mode: "physical" (N, B, T, K scaled with dt: round-trips at every rate) or "paper" (the
    paper's recursion, eqs. 11-17, evaluated at dt = 1/rate; its constants at 200 Hz).
    """

    def __init__(
        self,
        profile: str | Path | Profile | Mapping[str, Any] = "paper",
        rate_hz: float = 200.0,
        seed: int | np.random.SeedSequence | None = None,
        mode: str = "physical",
    ) -> None:
        self.profile = load_profile(profile)
        self.mode = check_mode(mode)
        rate = check_rate(rate_hz, self._own_rate())
        for other in SUPPORTED_RATES_HZ:  # a profile must run at every rate a driver may set
            for axis in self.profile.axes:
                axis_coefficients(axis, other, self.mode)
        seed_seq = (
            seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        )
        self.seed_sequence = seed_seq
        self._axes = [
            _AxisStream(axis, child, self.mode)
            for axis, child in zip(self.profile.axes, seed_seq.spawn(3))
        ]
        self._uses_time = any(a.R > 0 or a.sine for a in self.profile.axes)
        # Q is output-referred: generate_referred hands it apart (the chip filters the rest)
        self._split = any(a.Q > 0 for a in self.profile.axes)
        self._rate_hz = 0.0
        self._apply_rate(rate)
        # time of sample k is t_ref + (k - k_ref) dt (first sample at t = dt)
        self._t_ref = 0.0
        self._k_ref = -1
        self._k = 0  # index of the next sample handed out
        self._buf_start = 0
        self._buf_out = np.empty((0, 3))
        self._buf_post: np.ndarray | None = np.empty((0, 3)) if self._split else None
        self._buf_normals: list[dict[str, np.ndarray | None]] = []
        self._buf_state_before: list[tuple[Any, ...]] = []

    # -- public interface --------------------------------------------------------------------

    @property
    def rate_hz(self) -> float:
        """Current output data rate in Hz."""
        return self._rate_hz

    @property
    def samples_generated(self) -> int:
        """Number of samples handed out so far (index of the next sample)."""
        return self._k

    def generate(self, n: int) -> np.ndarray:
        """The next n samples, shape (n, 3), deg/s, constant bias included."""
        pre, post = self.generate_referred(n)
        return pre if post is None else pre + post

    def generate_referred(self, n: int) -> tuple[np.ndarray, np.ndarray | None]:
        """The next n samples as (sensing element's noise, output-referred noise or None):
        the first is what a chip filters (every term but Q, bias included), the second the
        Q term, None when no axis has one. Their sum is ``generate``'s output."""
        try:
            n = operator.index(n)
        except TypeError:
            raise TypeError(f"number of samples must be an integer, got {n!r}") from None
        if n < 0:
            raise ValueError(f"number of samples must not be negative, got {n}")
        pos = self._k - self._buf_start
        available = self._buf_out.shape[0] - pos
        bpost = self._buf_post
        if n <= available:
            self._k += n
            return (self._buf_out[pos : pos + n].copy(),
                    None if bpost is None else bpost[pos : pos + n].copy())
        out = np.empty((n, 3))
        post = None if bpost is None else np.empty((n, 3))
        out[:available] = self._buf_out[pos:]
        if post is not None and bpost is not None:
            post[:available] = bpost[pos:]
        self._k += available
        rest = n - available
        if rest >= _BUFFER_SAMPLES:
            self._compute_direct(out[available:], None if post is None else post[available:])
            self._k += rest
            self._buf_start = self._k
            self._buf_out = np.empty((0, 3))
            self._buf_post = None if post is None else np.empty((0, 3))
        else:
            self._refill_buffer()
            out[available:] = self._buf_out[:rest]
            if post is not None and self._buf_post is not None:
                post[available:] = self._buf_post[:rest]
            self._k += rest
        return out, post

    def _own_rate(self) -> float | None:
        """The rate the profile was identified at (physical mode: its terms scale with dt at
        any rate; the paper's constants are of 200 Hz), beside the BMG160's ODRs."""
        output = self.profile.output
        return output.rate_hz if output is not None and self.mode == "physical" else None

    def set_rate(self, rate_hz: float) -> None:
        """Continue the same realisation at another output data rate.

        The Gauss-Markov and random-walk states of the last sample handed out carry over; the
        coefficients (white std, alpha, gains) change from the next sample on.
        """
        rate = check_rate(rate_hz, self._own_rate())
        if rate == self._rate_hz:
            return
        # coefficients first: if the profile cannot run at this rate, nothing has changed
        coefs = [axis_coefficients(s.axis, rate, self.mode) for s in self._axes]
        last = self._k - 1
        t_last = self._t_ref + (last - self._k_ref) * (1.0 / self._rate_hz)
        pos = self._k - self._buf_start
        pending = self._buf_out.shape[0] - pos
        if pending > 0:
            # rewind every axis to the state of the last sample handed out
            for i, stream in enumerate(self._axes):
                poles_before, q_before = self._buf_state_before[i]
                normals = self._buf_normals[i]
                for pole, before in zip(stream._all, poles_before):
                    pole.set_state(before)
                    pole.skip(pos)
                wq = normals["quant"]
                stream.quant_prev = float(wq[pos - 1]) if (wq is not None and pos > 0) else q_before
        self._apply_rate(rate, coefs)
        self._t_ref, self._k_ref = t_last, last
        if pending > 0:
            kept = [
                {k: (v[pos:] if v is not None else None) for k, v in nm.items()}
                for nm in self._buf_normals
            ]
            self._fill_buffer_from(kept, self._k, pending)

    def checkpoint(self) -> tuple[Any, ...]:
        """The generator's state now, for ``restore``: a consumer that drew samples ahead (the
        device model) can go back to the last sample it used and continue from there, e.g.
        at another rate, exactly as if it had never drawn further (chunk invariance)."""
        axes = tuple(
            (
                {name: rng.bit_generator.state for name, rng in stream.rng.items()},
                stream.state(),
                stream.coef,
            )
            for stream in self._axes
        )
        # the buffer arrays are replaced, never written in place: references are enough
        return (axes, self._rate_hz, self._t_ref, self._k_ref, self._k, self._buf_start,
                self._buf_out, self._buf_post, self._buf_normals, self._buf_state_before)

    def restore(self, checkpoint: tuple[Any, ...]) -> None:
        """Go back to the state saved by ``checkpoint`` (of this generator)."""
        (axes, self._rate_hz, self._t_ref, self._k_ref, self._k, self._buf_start,
         self._buf_out, self._buf_post, self._buf_normals, self._buf_state_before) = checkpoint
        for stream, (rng_states, (poles, q), coef) in zip(self._axes, axes):
            for name, state in rng_states.items():
                stream.rng[name].bit_generator.state = state
            for pole, pole_state in zip(stream._all, poles):
                pole.set_state(pole_state)
            stream.quant_prev, stream.coef = q, coef

    # -- internals ---------------------------------------------------------------------------

    def _apply_rate(self, rate: float, coefs: list[AxisCoefficients] | None = None) -> None:
        if coefs is None:
            coefs = [axis_coefficients(s.axis, rate, self.mode) for s in self._axes]
        for stream, coef in zip(self._axes, coefs):
            stream.set_coefficients(coef)
        self._rate_hz = rate

    def _times(self, k0: int, n: int) -> np.ndarray | None:
        if not self._uses_time:
            return None
        return self._t_ref + (np.arange(k0, k0 + n) - self._k_ref) * (1.0 / self._rate_hz)

    def _compute_direct(self, out: np.ndarray, post: np.ndarray | None = None) -> None:
        """Compute out.shape[0] samples starting at self._k, block by block, into out (and
        the output-referred term into post)."""
        total = out.shape[0]
        for start in range(0, total, _BLOCK_SAMPLES):
            m = min(_BLOCK_SAMPLES, total - start)
            t = self._times(self._k + start, m)
            block = out[start : start + m]
            for i, stream in enumerate(self._axes):
                stream.compute(stream.draw(m), t, block[:, i],
                               None if post is None else post[start : start + m, i],
                               consume=True)

    def _refill_buffer(self) -> None:
        normals = [stream.draw(_BUFFER_SAMPLES) for stream in self._axes]
        self._fill_buffer_from(normals, self._k, _BUFFER_SAMPLES)

    def _fill_buffer_from(
        self, normals: list[dict[str, np.ndarray | None]], k0: int, m: int
    ) -> None:
        self._buf_start = k0
        self._buf_out = np.empty((m, 3))
        post = np.empty((m, 3)) if self._split else None
        self._buf_post = post
        self._buf_normals = normals
        self._buf_state_before = [s.state() for s in self._axes]
        t = self._times(k0, m)
        for i, stream in enumerate(self._axes):
            stream.compute(normals[i], t, self._buf_out[:, i], None if post is None else post[:, i])
