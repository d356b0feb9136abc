"""``BMG160``: the register-level model of the Bosch BMG160 gyroscope.

Front ends reach the chip only through its primitives (``write``, ``read``, ``i2c_write``,
``i2c_read``, ``peek``, ``dump``; docs/architecture.md). This module holds the lock, the
sample schedule and catch-up, the primitives, the hooks and reset; the parts live beside it:
``access`` (one bus transaction), ``regmap`` (what each register does, by name),
``datapath`` and ``true_rate`` (true rate to counts, in blocks), ``emission`` (samples
through the hooks and the per-sample engines), ``engines``, ``interrupts`` and ``fifo``.
Section numbers refer to the register specification.

Speed: the data path is computed ahead in blocks; the per-sample engines run only when enabled.
Time is integer nanoseconds: sample k of a run is at ``anchor + k * period``."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from bmg160_emu.clock import NS_PER_S, RealTimeClock, VirtualClock, seconds_to_ns
from bmg160_emu.device import access, contract, datapath, emission, engines, environment, regmap
from bmg160_emu.device import fifo as fifo_mod
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.engines import NEVER, power_mode
from bmg160_emu.device.interrupts import Interrupts
from bmg160_emu.device.part_spec import BMG160_PART, Part
from bmg160_emu.device.registers import FIRST_OUTSIDE_MAP, address_of, field_of
from bmg160_emu.device.true_rate import QueuedRates, TrueRate, streamed_rate, true_rate_source

log = logging.getLogger(__name__)
NORMAL, DEEP_SUSPEND, SUSPEND, FAST_POWER_UP, POWER_SAVE = engines.MODES  # names as before
VALID_ADDRESSES = contract.VALID_ADDRESSES

_RATE_X_LSB, _RATE_END = address_of("RATE_X_LSB"), address_of("RATE_Z_MSB") + 1
_RANGE, _BW, _LPM1, _LPM2 = (address_of(name) for name in ("RANGE", "BW", "LPM1", "LPM2"))
_RATE_HBW, _BGW_SOFTRESET = address_of("RATE_HBW"), address_of("BGW_SOFTRESET")
_DATA_HIGH_BW = field_of("RATE_HBW", "data_high_bw").mask


class BMG160(environment.EnvironmentInputs):
    """A BMG160 gyroscope at register level.

    ``seed`` with ``address`` (0x68/0x69) seeds the noise, so two chips sharing a master
    seed have independent noise. ``noise=False`` gives a noiseless chip. ``clock`` is a
    new ``VirtualClock`` unless one is passed (several chips can share it, and its lock) or a
    ``RealTimeClock``. ``sensitivity`` is "binary" (32768/FS, default), "nominal" or five
    LSB/(deg/s) figures for RANGE codes 0..4. ``hold_data_int=True`` holds data_int until
    the rate registers are read (an emulator convenience, not chip behaviour). ``strict``
    logs questionable driver behaviour to ``strict_log`` and the ``bmg160_emu.device.chip`` logger.
    ``errors``, ``unit``, ``acceleration_g``: the unit's error budget (device.environment)."""

    # state kept by reset and regmap.update_engine_flags
    _msb_latch: list[int | None]
    _latched: bool
    _fifo_mode: int
    _fifo_store_mode: int
    _fifo_int_on: bool
    _per_sample: bool
    _plain: bool  # no per-sample engine, no FIFO storage or interrupt (regmap.update_engine_flags)
    part: Part = BMG160_PART  # name, pins and register table (part_spec; device.parts: others)

    def __init__(
        self,
        seed: int | None = None,
        *,
        profile: Any = "paper",
        noise: bool = True,
        noise_mode: str = "physical",
        clock: VirtualClock | RealTimeClock | None = None,
        address: int = 0x68,
        sensitivity: str | Sequence[float] = choice.DEFAULT_SENSITIVITY,
        startup_time_s: float = choice.STARTUP_TIME_NS / NS_PER_S,
        hold_data_int: bool = False,
        strict: bool = False,
        temperature_c: float | Callable[[float], float] = 23.0,
        true_rate: Any = (0.0, 0.0, 0.0),
        mounting: Any = None,
        scale_factor: Any = None,
        misalignment: Any = None,
        nvm_image: bytes | None = None,
        nvm_remain: int = choice.NVM_DEFAULT_REMAIN,
        errors: Any = None,
        unit: int | None = None,
        acceleration_g: Any = (0.0, 0.0, 0.0),
    ) -> None:
        contract.check_chip_options(address, noise_mode, seed)
        self.address = address
        clock = VirtualClock() if clock is None else clock
        contract.check_clock(clock)
        # on a VirtualClock the chip takes the clock's lock as its own: one acquisition covers
        # the chip and the time it moves (the lock stays the chip's if the clock is replaced)
        self.lock = clock.lock if isinstance(clock, VirtualClock) else threading.RLock()
        self.clock = clock
        self.sample_hooks: list[Callable[..., Any]] = []
        self.truth_hooks: list[Callable[..., Any]] = []
        self.strict = bool(strict)
        self.strict_log: list[str] = []
        self.hold_data_int = bool(hold_data_int)
        self.inject_bist_failure = False  # the next self-test reports bist_fail (6.8)
        self._startup_ns = seconds_to_ns(startup_time_s)
        self._sensitivity = datapath.sensitivity_table(sensitivity)
        transform = datapath.body_to_sensor(mounting, scale_factor, misalignment)
        self.seed = seed
        generator = datapath.noise_generator(profile, noise_mode, seed, address) if noise else None
        engines.Thermometer.check(temperature_c)
        self._thermometer = engines.Thermometer(temperature_c)
        self._budget = environment.ErrorBudget.of(self, errors, unit, acceleration_g, generator or profile)
        self._path = datapath.DataPath(transform, generator, self._budget)
        image = choice.NVM_DEFAULT_IMAGE if nvm_image is None else nvm_image
        self._nvm = engines.Nvm(image, nvm_remain)
        self._bist = engines.SelfTest()
        self._k = -1  # index of the last sample produced
        self._step_s, self._step_ns = 0.0, 0  # advance's last step (s) and its rounding (ns)
        self._block: datapath.Block | None = None
        self._span = (0, 0)  # the samples computed ahead, in pieces (datapath.next_piece)
        self._span_used = datapath.SPAN  # samples of the last span used before a change
        self._rate: TrueRate = true_rate_source((0.0, 0.0, 0.0), None, first_k=0, first_ns=0)
        self._pointer = 0
        self._next_ns = NEVER
        self._emitting = False
        self._reset_state(self.clock.now_ns(), powered=choice.POWERED_UP_AT_CONSTRUCTION)
        self._apply_true_rate(true_rate, None)

    # ------------------------------------------------------------------ inputs and state

    def set_temperature(self, temperature_c: float | Callable[[float], float]) -> None:
        """Die temperature in deg C: a constant or a callable of time in seconds."""
        engines.Thermometer.check(temperature_c)
        with self.lock:
            self._thermometer.temperature_c = temperature_c

    def set_true_rate(self, rate: Any, *, sample_rate_hz: float | None = None) -> None:
        """True body angular rate in deg/s: a 3-tuple, a callable ``t -> 3-vector`` or an
        ``(n, 3)`` array of samples. Samples are taken one per output sample from the next
        one on (or at ``sample_rate_hz``, held between rows); the last row then holds."""
        with self.lock:
            self._rate_due()
            self._apply_true_rate(rate, sample_rate_hz)

    def stream_true_rate(self, rate_dps: Sequence[float]) -> None:
        """The true body rate, 3 numbers in deg/s, from the next output sample on, for a loop
        with a new rate every step: ``set_true_rate`` of the 3 numbers, bit for bit, checked
        faster; each sample is computed once (a one-sample piece, ``datapath.next_piece``)."""
        source = streamed_rate(rate_dps)
        with self.lock:
            self._rate_due()
            self._invalidate()
            self._rate = source

    def queue_true_rate(self, rate_dps: Sequence[float]) -> None:
        """``stream_true_rate`` without computing anything now: the rate holds from the next
        output sample on, and the samples are computed when something reads them, all that
        are due at once (a simulator's 5 ms steps against a driver reading the FIFO at 20 Hz).
        The same samples as ``stream_true_rate``'s to rounding (~1e-15 of the rate)."""
        row = streamed_rate(rate_dps).rate_dps
        with self.lock:
            if isinstance(self._rate, QueuedRates):
                self._rate.add(emission.first_not_due(self, self.clock.now_ns()), row)
                return
            self._rate_due()
            self._invalidate()
            self._rate = QueuedRates(self._k + 1, row)

    def _rate_due(self) -> None:
        """The samples due before a new true rate; those a failing rate function could not
        produce come from the new one (it is being replaced)."""
        try:
            self._now()
        except Exception:
            if not self._rate.failed:
                raise

    def _apply_true_rate(self, rate: Any, sample_rate_hz: float | None) -> None:
        first_ns = self._next_ns if self._next_ns < NEVER else self.clock.now_ns()
        source = true_rate_source(rate, sample_rate_hz, first_k=self._k + 1, first_ns=first_ns)
        self._invalidate()
        self._rate = source

    @property
    def clock(self) -> VirtualClock | RealTimeClock:
        """The chip's time base; it may be replaced (``run`` and ``umockdev`` do, under
        ``lock``)."""
        return self._clock

    @clock.setter
    def clock(self, clock: VirtualClock | RealTimeClock) -> None:
        contract.check_clock(clock)
        self._clock = clock
        # a plain VirtualClock guarded by this chip's lock: advance and read use its time
        # directly (VirtualClock.advance_ns and now_ns inlined, tools/bench_fake_smbus.py)
        self._virtual = clock if type(clock) is VirtualClock and clock.lock is self.lock else None

    @property
    def _sample_seq(self) -> int:
        """Samples produced since the last reset (every sample moves _k on by one)."""
        return self._k - self._seq_base

    @property
    def _have_sample(self) -> bool:
        return self._k > self._seq_base

    @property
    def time(self) -> float:
        """The chip's current time in seconds (every bus transaction logs it)."""
        clock = self._virtual
        return clock._ns / NS_PER_S if clock is not None else self.clock.now()

    @property
    def power_mode(self) -> str:
        return power_mode(self._regs[_LPM1], self._regs[_LPM2])

    @property
    def odr_hz(self) -> int:
        return self._odr

    @property
    def sensitivity(self) -> float:
        """LSB per deg/s of the current range."""
        return self._sensitivity[regmap.range_code(self._regs[_RANGE])]

    @property
    def sensitivity_table(self) -> tuple[float, ...]:
        return self._sensitivity

    @property
    def int1(self) -> bool:
        """INT1 asserted (logical state, before level and output type)."""
        with self.lock:
            return regmap.pins(self, self._now())[0]

    @property
    def int2(self) -> bool:
        with self.lock:
            return regmap.pins(self, self._now())[1]

    def int_pin_level(self, pin: int) -> int:
        """Electrical level 0/1 of INT1 or INT2 for a push-pull output (INT_EN_1 lvl bit)."""
        with self.lock:
            return regmap.pin_level(self, pin, self._now())

    def offsets_lsb(self) -> tuple[int, int, int]:
        """The three 12-bit offsets of OFC1..OFC4 and TRIM_GP0 (4.24)."""
        return engines.offsets_from(self._regs)

    @property
    def offset_lsb_dps(self) -> float:
        """deg/s per offset LSB: one count of the +-2000 deg/s range (6.9, unconfirmed)."""
        return 1.0 / self._sensitivity[choice.OFFSET_LSB_RANGE_CODE]

    def _offset_dps(self) -> np.ndarray:
        return engines.offsets_dps(self._regs, self.offset_lsb_dps)

    @property
    def nvm_image(self) -> bytes:
        return bytes(self._nvm.image)

    @property
    def _noise_gen(self) -> Any:
        return self._path.noise.generator

    # ------------------------------------------------------------------ primitives

    def write(self, reg: int, data: bytes | Sequence[int]) -> None:
        """One bus write transaction of ``data`` starting at ``reg`` (auto-increment)."""
        reg = self._check_reg(reg)
        payload = self._check_data(data)
        with self.lock:
            self._pointer = access.write_burst(self, reg, payload, self._now())

    def read(self, reg: int, n: int = 1) -> bytes:
        """One bus read transaction of ``n`` bytes from ``reg`` with every side effect."""
        lock = self.lock  # acquire/try/finally: half the cost of ``with`` on CPython 3.11
        lock.acquire()  # (75 against 150 ns, tools/bench_fake_smbus.py's hot path)
        try:
            clock = self._virtual
            now = clock._ns if clock is not None else self.clock.now_ns()
            if now >= self._next_ns:
                self._catch_up(now)
            if reg == _RATE_X_LSB and n == 6 and reg.__class__ is int:  # fast path: X, Y, Z
                if self._latched:
                    self._msb_latch = [None, None, None]
                    self._latched = False
                self._data_ready_pending = False
                self._pointer = _RATE_END
                return self._cur
            reg = self._check_reg(reg)
            n = self._check_count(n)
            data, self._pointer = access.read_burst(self, reg, n, now)
            return data
        finally:
            lock.release()

    def i2c_write(self, data: bytes | Sequence[int]) -> None:
        """I2C write: ``data[0]`` sets the register pointer, the rest is written from it.

        ``read`` and ``write`` leave the pointer where their transaction ended too, as a
        combined I2C transaction does."""
        payload = self._check_data(data)
        if not payload:
            return
        with self.lock:
            now = self._now()
            self._pointer = payload[0]
            if len(payload) > 1:
                self._pointer = access.write_burst(self, payload[0], payload[1:], now)

    def i2c_read(self, n: int) -> bytes:
        """I2C read of ``n`` bytes from the current register pointer."""
        n = self._check_count(n)
        with self.lock:
            now = self._now()
            data, self._pointer = access.read_burst(self, self._pointer, n, now)
            return data

    @property
    def pointer(self) -> int:
        """The I2C register pointer."""
        return self._pointer

    def peek(self, reg: int) -> int:
        """Register content without side effects (no MSB latch, no FIFO pop)."""
        reg = self._check_reg(reg)
        with self.lock:
            return access.peek_reg(self, reg, self._now())

    def dump(self) -> bytes:
        """The 64 registers 0x00..0x3F, without side effects."""
        with self.lock:
            now = self._now()
            return bytes(access.peek_reg(self, a, now) for a in range(FIRST_OUTSIDE_MAP))

    def advance(self, seconds: float) -> None:
        """Advance the clock; the chip produces exactly one sample per output period."""
        try:  # contract.duration_ns and emit_batch of one sample, inlined: a polling
            if seconds == self._step_s:  # driver's hot path (tools/bench_fake_smbus.py):
                ns = self._step_ns  # the same step as last time, as round() made it (80 ns)
            else:
                self._step_s, self._step_ns = seconds, (ns := round(seconds * 1e9))
        except (TypeError, ValueError, OverflowError):
            ns = -1
        if ns < 0:
            ns = contract.duration_ns(seconds)
        lock = self.lock  # acquired as in read
        lock.acquire()
        try:
            clock = self._virtual
            if clock is not None:  # VirtualClock.advance_ns inlined: its lock is held
                now = clock._ns = clock._ns + ns
            else:
                now = self.clock.advance_ns(ns)
            t = self._next_ns
            if now < t:
                return
            period = self._period_ns
            if now >= t + period or not self._plain or self.sample_hooks or self.truth_hooks:
                self._catch_up(now)
                return
            k = self._k + 1
            b = self._block
            if b is None or k >= b.end:
                b = self._block_for(k)
            i = 6 * (k - b.k0)
            self._cur = b.rate_bytes[i:i + 6]
            self._k = k
            self._last_sample_ns = t
            self._next_ns = t + period
            self._data_ready_pending = True
        finally:
            lock.release()

    def poke(self, reg: int, value: int) -> None:
        """Set a register's content directly, as an upset bit would: no access rules, no
        trigger actions; the data path follows from the next sample (fault injection)."""
        reg = self._check_reg(reg)
        if not 0 <= value <= 0xFF:
            raise ValueError("register value must be 0..255")
        if reg >= FIRST_OUTSIDE_MAP:
            return
        with self.lock:
            access.poke_reg(self, reg, value, self._now())

    def power_on_reset(self) -> None:
        """Every register back to reset values, as after a brown-out; data after start-up."""
        with self.lock:
            self._reset_state(self._now(), powered=False)
            self._pointer = 0

    def soft_reset(self) -> None:
        """The effect of writing 0xB6 to BGW_SOFTRESET (6.6)."""
        self.write(_BGW_SOFTRESET, bytes((regmap.SOFTRESET_KEY,)))

    _check_reg = staticmethod(contract.check_register)
    _check_count = staticmethod(contract.check_count)
    _check_data = staticmethod(contract.check_data)

    def _strict(self, message: str) -> None:
        if self.strict:
            self.strict_log.append(message)
            log.warning("BMG160 0x%02X: %s", self.address, message)

    # ------------------------------------------------------------------ reset and schedule

    def _reset_state(self, now: int, *, powered: bool) -> None:
        """Soft reset, power-on reset and leaving deep suspend (6.6, 6.7)."""
        self._block = None
        self._regs = bytearray(self.part.reset_values)
        self.part.load_nvm(self._nvm, self._regs)
        self._nvm.busy_until_ns = -1
        self._cur = bytes(6)
        self._seq_base = self._k  # samples since this reset: _k - _seq_base
        self._last_sample_ns = -NEVER
        self._data_ready_pending = False
        self._msb_latch = [None, None, None]
        self._latched = False
        self._fifo = fifo_mod.Fifo()
        self._bypass_seq = 0
        self._irq = Interrupts()
        self._bist.start_ns = None
        self._foc: engines.FastOffset | None = None
        self._budget.power_cycle()
        self._set_filter()
        self._path.restart_filter = True
        regmap.update_engine_flags(self)
        self._start_sampling(now if powered else now + self._startup_ns)

    def _start_sampling(self, first_ns: int) -> None:
        self._invalidate()
        self._anchor_ns = first_ns
        self._anchor_k = self._k + 1
        self._next_ns = first_ns
        self._data_start_ns = first_ns
        self._path.restart_filter = True

    def _stop_sampling(self) -> None:
        self._invalidate()
        self._next_ns = NEVER
        # 5.2: TEMP keeps its last conversion until the next sample (frozen while not sampling)
        self._thermometer.freeze(self._have_sample, self._last_sample_ns)

    # ------------------------------------------------------------------ data path

    def _set_filter(self, *, running: bool = False) -> None:
        """ODR and filter from BW; the noise realisation carries on (a running filter too)."""
        odr, bandwidth = regmap.bandwidth(self._regs[_BW])
        set_filter = self._path.change_bandwidth if running else self._path.set_filter
        set_filter(odr, bandwidth, used_end=self._k + 1)
        self._odr, self._period_ns = odr, NS_PER_S // odr

    def _invalidate(self) -> None:
        """Drop the computed-ahead samples after the current one (configuration changed)."""
        if self._block is not None:
            self._span_used = max(self._k + 1 - self._span[0], 1)
        self._path.invalidate(self._block, self._k)
        self._block = None

    def _times_ns(self, k0: int, n: int) -> np.ndarray:
        return self._anchor_ns + (np.arange(k0, k0 + n) - self._anchor_k) * self._period_ns

    def _block_for(self, k: int, want: int = 1) -> datapath.Block:
        """The block holding sample k, built for ``want`` samples from k if it is missing."""
        b = self._block
        if b is not None and b.k0 <= k < b.end:
            return b
        first, n, self._span = datapath.next_piece(b, k, want, self._span, self._span_used)
        if not self._rate.ahead:  # rates still to come (queue_true_rate): only what is due
            n = min(n, want)
        body = self._rate.block(k, n, self._times_ns)
        b = self._block = self._path.build(
            k, body, self._offset_dps(), self.sensitivity,
            bool(self._regs[_RATE_HBW] & _DATA_HIGH_BW), self._rate.constant, first=first)
        return b

    # ------------------------------------------------------------------ catch-up

    def _now(self) -> int:
        now = self.clock.now_ns()
        if now >= self._next_ns:
            self._catch_up(now)
        return now

    def _catch_up(self, now: int) -> None:
        """Produce every sample due by ``now`` (between transactions, never inside one)."""
        emission.catch_up(self, now)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(address=0x{self.address:02X}, t={self.clock.now():.6f} s, "
                f"mode={self.power_mode}, odr={self._odr} Hz)")
