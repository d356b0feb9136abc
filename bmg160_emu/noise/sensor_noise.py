"""The sensing element's noise as an output carries it: through the output low-pass, in
chunks that make it independent of how far ahead it is computed (``SensorNoise``, what a
chip's data path adds to its true rate), and a profile's noise as ``generate`` writes it,
through the profile's own output stage (``ProfileNoise``, ``profile_noise``).

A chip and ``generate`` use the same class, so a file of noise and a chip's registers hold
the same model (docs/noise-engine.md, "Where each term enters").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bmg160_emu.noise.bandwidths import BANDWIDTHS, LOWPASS_ORDER, code_filter
from bmg160_emu.noise.lowpass import LowPass
from bmg160_emu.noise.response_fir import ResponseFIR
from bmg160_emu.noise.worker_thread import WorkerThread

NOISE_CHUNK = 2048  # noise computed in chunks of this many samples (a multiple of the
# filter's 1024-sample pieces, lowpass.py), each with its filter state kept
PIECE = 16 * NOISE_CHUNK  # samples generated and filtered at once within a draw: the three
# 768 kB arrays of a piece stay in the cache between the generator and the filter
DRAW_AHEAD = 2 * NOISE_CHUNK  # the least a chip's draw covers: a draw's fixed cost (the
# generator's checkpoint, the calls) over 4096 samples, not 2048: 145 -> 130 ns a sample of
# noise (tools/bench_fake_smbus.py); the same bits, the filter still runs chunk by chunk


class SensorNoise:
    """The sensing element's noise by sample index: raw, and as the chip's output carries it.

    Where the noise enters (docs/noise-engine.md): in ``physical`` mode the noise is made in
    the sensing element, before the chip's digital low-pass, so the filtered output carries
    it through the filter of the BW code and the unfiltered (data_high_bw) output raw; only
    the profile's Q term (an output's quantization, IEEE 952) is added after the filter. In
    ``paper`` mode the paper's recursion is the chip's output (output-referred, its Table 3):
    both outputs carry it unfiltered. The true rate has its own filter (``configure`` returns it
    to the chip's ``DataPath``); the filter is linear, so the two filters together are the chip's one filter of rate + noise.

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
                 sequential: bool = False, worker: WorkerThread | None = None) -> None:
        self.generator = generator
        # generate's: a large sequential draw filters each piece on this worker while the
        # generator draws the next (noise.worker_thread; lfilter releases the GIL)
        self.worker = worker
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
                  order: int = LOWPASS_ORDER) -> LowPass | None:
        """The chip's ODR and filter from sample ``used_end`` on (None: no filter); noise
        drawn for later samples is redrawn. Nothing changes if both are as they were.

        Returns a new filter of that design at rest, for the true rate the data path runs
        beside the noise (None without a filter): a BW write reaches the noise layer once."""
        rate_filter = (None if bandwidth_hz is None
                       else LowPass(float(odr_hz), float(bandwidth_hz), int(order)))
        gen = self.generator
        config = ((float(odr_hz), bandwidth_hz, int(order)) if self.filtered
                  else (float(odr_hz),))
        if gen is None or config == self.config:
            self.config = config
            return rate_filter
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
        return rate_filter

    def configure_code(self, code: int, used_end: int) -> tuple[int, LowPass]:
        """The chip's BW ``code`` (0..7, bandwidths.py) from sample ``used_end`` on: its ODR
        and its filter for the noise (``configure``). Returns (ODR Hz, the true rate's filter)."""
        odr_hz, bandwidth_hz = BANDWIDTHS[code]
        rate_filter = self.configure(odr_hz, bandwidth_hz, used_end)
        assert rate_filter is not None  # every BW code has a filter
        return odr_hz, rate_filter

    def take(self, k0: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(unfiltered, filtered) noise of samples k0 .. k0 + n - 1, deg/s; samples before
        k0 are forgotten (before a draw, else once NOISE_CHUNK of them are held)."""
        if self.generator is None:
            zeros = np.zeros((n, 3))
            return zeros, zeros
        if k0 < self.k0:
            raise RuntimeError(f"noise of sample {k0} was forgotten (held from {self.k0})")
        if k0 + n > self.end:
            if k0 > self.k0:
                self._forget(min(k0, self.end))
            self._draw(k0 + n)
            if k0 > self.k0:  # a gap: samples drawn and never used
                self._forget(k0)
        elif k0 - self.k0 >= NOISE_CHUNK:  # (forgotten a chunk at a time: a closed loop takes
            self._forget(k0)  # one sample a step, and a cut of two views is most of that)
        i = k0 - self.k0
        return self.raw[i:i + n], self.out[i:i + n]

    def _draw(self, end: int) -> None:
        """Whole chunks from self.end until ``end`` is covered (one generator checkpoint),
        generated and filtered in pieces of PIECE samples, each while it is in the cache
        (the generator is chunk invariant: the same samples as one call); a sequential
        (generate's) draw ends at ``end`` exactly."""
        gen = self.generator
        if self.sequential:  # generate: exactly what is asked, so nothing is held over and
            total = end - self.end  # the next draw is one call into fresh arrays, no copy
        else:  # (the recursion and the generator give the same bits however cut)
            total = max(-(-(end - self.end) // NOISE_CHUNK) * NOISE_CHUNK, DRAW_AHEAD)
        self.draws.append((self.end, gen.checkpoint()))
        flt = self.filter
        held = self.end - self.k0
        if (self.sequential and held == 0 and flt is not None and self.worker is not None
                and self.worker.splits(total, PIECE)):  # (else one call: no copies)
            self._draw_beside(total)
            return
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
        if held == 0 and total <= PIECE:  # a chip's usual draw (take forgot what it used):
            # the generator's and the filter's fresh arrays kept as they come, not copied into
            # new ones (the same operations, so the same bits)
            pre, post = gen.generate_referred(total)
            self.raw = raw = pre if post is None else pre + post
            if flt is None:
                self.out = raw
            else:
                assert self.state is not None  # set when the filter was configured
                self.out, self.state = flt.run_pieces(pre, self.state, NOISE_CHUNK)
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

    def _draw_beside(self, total: int) -> None:
        """A sequential draw of ``total`` samples from nothing held, in pieces of PIECE: the
        recursion of each piece (its state from the previous) on the worker while the
        generator draws the next; the same operations per sample as one call, so the same bits."""
        from scipy.signal import lfilter

        gen, flt = self.generator, self.filter
        assert flt is not None and self.worker is not None
        raw, out = np.empty((total, 3)), np.empty((total, 3))

        def draw(start: int, m: int) -> tuple[np.ndarray, np.ndarray | None]:
            return gen.generate_referred(m)

        def work(start: int, drawn: tuple[np.ndarray, np.ndarray | None]) -> None:
            pre, post = drawn
            rows = slice(start, start + pre.shape[0])
            out[rows], self.state = lfilter(flt.b, flt.a, pre, axis=0, zi=self.state)
            if post is None:
                raw[rows] = pre
            else:
                np.add(pre, post, out=raw[rows])
                out[rows] += post

        self.worker.run_pieces(total, PIECE, draw, work)
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
            same = BANDWIDTHS[stage.bw_code] == (odr_hz, bandwidth_hz) and (
                order == LOWPASS_ORDER)
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
    profile's own output stage (``[output]``: a Butterworth order and corner, or a BW code;
    or each axis's measured ``response``, a minimum-phase FIR, noise.output_response) or a BW
    code's filter, then rounded to the profile's LSB, by the same ``SensorNoise`` a chip
    uses. ``generate(n)``: the next n samples (n, 3) in deg/s. ``notes``: what was left out
    and why (a filter above the Nyquist frequency, a response measured at another rate)."""

    def __init__(self, generator: Any, bandwidth_hz: float | None, order: int,
                 lsb_dps: float | None = None,
                 responses: list[np.ndarray | None] | None = None,
                 notes: list[str] | None = None, fir_threads: int | None = None) -> None:
        self.generator = generator
        self.lsb_dps = lsb_dps
        self.bandwidth_hz = bandwidth_hz
        self.order = order
        self.notes = list(notes or [])
        # one worker thread (or none) for both filters: the low-pass's pieces, then the FIR's
        self.worker = WorkerThread(fir_threads)
        self._noise = SensorNoise(generator, filtered=generator.mode == "physical",
                                  sequential=True, worker=self.worker)
        self._noise.configure(generator.rate_hz, bandwidth_hz, 0, order)
        self._k = 0
        self.responses = responses if responses and any(
            h is not None and h.size > 1 for h in responses) else None
        # each measured response's FIR with its memory (noise.response_fir: output k the same
        # dot product however the record is cut; on a second core when there is one)
        self.fir: ResponseFIR | None = None
        if self.responses is not None:
            self.fir = ResponseFIR(self.responses, worker=self.worker)
            # the FIRs start settled: their memory filled with the stream's first samples
            # (the realisation moves on by them, as SensorNoise's filter start does)
            settle = self.fir.settle_samples
            _, first = self._noise.take(0, settle)
            self._k = settle
            self.fir.start(first)

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
        if self.responses is not None:
            taps = "/".join(str(h.size) if h is not None else "1" for h in self.responses)
            parts.append(f"response{taps}taps")
        if self.lsb_dps:
            parts.append(f"lsb{self.lsb_dps:.6g}dps")
        return ",".join(parts) or "none"

    def generate(self, n: int) -> np.ndarray:
        if self.fir is not None and n:
            out = self.fir.run(n, self._take)
        else:
            out = self._take(n)
        if self.lsb_dps:
            return np.rint(out / self.lsb_dps) * self.lsb_dps
        return out  # rows handed out once: the buffer never writes them nor uses them again

    def _take(self, n: int) -> np.ndarray:
        """The next n samples of the sensing element's noise through the low-pass, if any."""
        _, out = self._noise.take(self._k, n)
        self._k += n
        return out


def profile_noise(profile: Any, rate_hz: float | None = None, seed: Any = None,
                  mode: str = "physical", bandwidth_code: int | None = None,
                  use_output: bool = True, fir_threads: int | None = None) -> ProfileNoise:
    """The noise ``generate`` writes for a profile: at ``rate_hz`` (default: the BW code's
    ODR, else the rate the profile's output stage was found at, else 200 Hz) through the BW
    code's filter when one is given, else the profile's own output stage (``use_output``):
    its Butterworth, or each axis's measured response at the rate it was measured at (the
    response holds the axis's bands as measured, so the generator leaves them out there);
    rounded to its LSB; physical mode only filters (paper mode is output-referred).
    ``fir_threads``: 1, or 2 to run the output filter (the low-pass's recursion, a measured
    response's FIR) on a second core beside the generator (None: 2 when the process may run
    on two CPUs; noise.worker_thread), the same bits.
    ValueError on a rate the code does not have."""
    import dataclasses

    from bmg160_emu.noise import NoiseGenerator, load_profile

    profile = load_profile(profile)
    stage = profile.output if use_output else None
    code = bandwidth_code
    if code is None and stage is not None and stage.bw_code is not None:
        code = stage.bw_code
    bandwidth: float | None = None
    order = LOWPASS_ORDER
    notes: list[str] = []
    if code is not None:
        odr, bandwidth = code_filter(code)
        if rate_hz is not None and float(rate_hz) != odr:
            raise ValueError(f"rate {float(rate_hz):g} Hz disagrees with BW code {code} "
                             f"(ODR {odr} Hz): give one of them")
        rate_hz = float(odr)
    elif stage is not None and stage.corner_hz is not None:
        bandwidth, order = stage.corner_hz, int(stage.order or order)
    if rate_hz is None and stage is not None and stage.rate_hz is not None:
        rate_hz = stage.rate_hz
    rate = 200.0 if rate_hz is None else float(rate_hz)
    if bandwidth is not None and code is None and not bandwidth < 0.99 * rate / 2.0:
        notes.append(f"the profile's output filter (order {order} at {bandwidth:g} Hz) is at "
                     f"or above the Nyquist frequency of {rate:g} Hz: left out (a filter "
                     "there passes everything a sampled output carries)")
        bandwidth = None
    responses: list[np.ndarray | None] | None = None
    measured = [a.response for a in profile.axes]
    if use_output and code is None and any(measured):
        found_at = stage.rate_hz if stage is not None else None
        if found_at is not None and abs(found_at - rate) < 1e-9 * rate:
            from bmg160_emu.noise.output_response import OutputResponse

            responses = [OutputResponse(rate, c).taps if c else None for c in measured]
            profile = dataclasses.replace(profile, **{
                name: dataclasses.replace(axis, band=()) if axis.response else axis
                for name, axis in zip(("x", "y", "z"), profile.axes)})
        else:
            notes.append(f"the profile's measured output response is of {found_at:g} Hz "
                         f"samples: not applied at {rate:g} Hz; the sensing element's noise "
                         "(its bands as resonators) is written without an output filter "
                         "(--bandwidth CODE filters it with the chip's)")
    generator = NoiseGenerator(profile, rate_hz=rate, seed=seed, mode=mode)
    lsb = stage.lsb_dps if stage is not None else None
    return ProfileNoise(generator, bandwidth, order, lsb, responses, notes, fir_threads)
