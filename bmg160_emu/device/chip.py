"""``BMG160``: the register-level model of the Bosch BMG160 gyroscope.

Front ends reach the chip only through its primitives (``write``, ``read``, ``i2c_write``,
``i2c_read``, ``peek``, ``dump``; docs/architecture.md). This module holds the lock, the
primitives, the hook lists, the inputs and the reset entry points; the chip's mutable state
and sample schedule are its ``ChipState`` (``state``), which the parts beside it take:
``register_access`` (one bus transaction), ``regmap`` (what each register does, by name),
``output_samples`` (the samples due, through the hooks and the per-sample engines);
``datapath`` and ``true_rate`` (true rate to counts, in blocks), ``fifo``, ``interrupts``,
``offsets``, ``self_test``, ``nvm`` and ``thermometer`` are the engines the state holds.
Section numbers refer to the register specification.

Speed: the data path is computed ahead in blocks; the per-sample engines run only when enabled.
Time is integer nanoseconds: sample k of a run is at ``anchor + k * period``."""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from bmg160_emu.clock import NEVER, NS_PER_S, RealTimeClock, VirtualClock, seconds_to_ns
from bmg160_emu.device import (
    contract,
    datapath,
    environment,
    offsets,
    output_samples,
    register_access,
    regmap,
)
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.nvm import Nvm
from bmg160_emu.device.output_samples import catch_up
from bmg160_emu.device.part_spec import BMG160_PART, Part
from bmg160_emu.device.registers import FIRST_OUTSIDE_MAP, address_of
from bmg160_emu.device.state import ChipState
from bmg160_emu.device.thermometer import Thermometer
from bmg160_emu.device.true_rate import (
    QueuedRates,
    streamed_rate,
    streamed_row,
    true_rate_source,
)
from bmg160_emu.noise.sensor_errors import SensorErrors

_RATE_X_LSB, _RATE_END = address_of("RATE_X_LSB"), address_of("RATE_Z_MSB") + 1
_BGW_SOFTRESET = address_of("BGW_SOFTRESET")


class BMG160:
    """A BMG160 gyroscope at register level.

    ``seed`` with ``address`` (0x68/0x69) seeds the noise, so two chips sharing a master
    seed have independent noise. ``noise=False`` gives a noiseless chip. ``clock`` is a
    new ``VirtualClock`` unless one is passed (several chips can share it, and its lock) or a
    ``RealTimeClock``. ``sensitivity`` is "binary" (32768/FS, default), "nominal" or five
    LSB/(deg/s) figures for RANGE codes 0..4. ``hold_data_int=True`` holds data_int until
    the rate registers are read (an emulator convenience, not chip behaviour). ``strict``
    logs questionable driver behaviour to ``strict_log`` and the ``bmg160_emu.device.chip`` logger.
    ``errors``, ``unit``, ``acceleration_g``: the unit's error budget (device.environment).

    ``state`` is the chip's state and sample schedule (``state.ChipState``): the interface of
    the chip's own parts, and of white-box tests; front ends use the primitives."""

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
        sensitivity_table = datapath.sensitivity_table(sensitivity)
        transform = datapath.body_to_sensor(mounting, scale_factor, misalignment)
        self.seed = seed
        generator = datapath.noise_generator(profile, noise_mode, seed, address) if noise else None
        Thermometer.check(temperature_c)
        image = choice.NVM_DEFAULT_IMAGE if nvm_image is None else nvm_image
        self.state = s = ChipState(
            self, self.part, sensitivity_table=sensitivity_table,
            startup_ns=seconds_to_ns(startup_time_s),
            thermometer=Thermometer(temperature_c), nvm=Nvm(image, nvm_remain))
        s.budget = environment.ErrorBudget.of(
            errors, unit, acceleration_g, generator or profile, seed=seed, address=address,
            thermometer=s.thermometer, times_ns=s.times_ns, source=profile)
        s.path = datapath.DataPath(transform, generator, s.budget)
        self._step_s, self._step_ns = 0.0, 0  # advance's last step (s) and its rounding (ns)
        self._pointer = 0
        s.reset(self.clock.now_ns(), powered=choice.POWERED_UP_AT_CONSTRUCTION)
        self._apply_true_rate(true_rate, None)

    # ------------------------------------------------------------------ inputs and state

    def set_temperature(self, temperature_c: float | Callable[[float], float]) -> None:
        """Die temperature in deg C: a constant or a callable of time in seconds."""
        Thermometer.check(temperature_c)
        with self.lock:
            self.state.thermometer.temperature_c = temperature_c

    def set_acceleration(self, acceleration_g: Any) -> None:
        """Acceleration the chip feels, in g in its own frame (3 numbers, or a callable of t
        in seconds): it drives the g-sensitivity of the unit's errors from the next sample."""
        with self.lock:
            self._now()
            self.state.invalidate()
            self.state.budget.set_acceleration(acceleration_g)

    @property
    def sensor_errors(self) -> SensorErrors:
        """The unit's deterministic errors (bmg160_emu.noise.sensor_errors)."""
        return self.state.budget.errors

    @property
    def turn_on_bias_dps(self) -> np.ndarray:
        """The turn-on bias of the current power cycle, deg/s per axis."""
        return self.state.budget.turn_on_bias_dps.copy()

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
            self.state.invalidate()
            self.state.rate = source

    def queue_true_rate(self, rate_dps: Sequence[float]) -> None:
        """``stream_true_rate`` without computing anything now: the rate holds from the next
        output sample on, and the samples are computed when something reads them, all that
        are due at once (a simulator's 5 ms steps against a driver reading the FIFO at 20 Hz).
        The same samples as ``stream_true_rate``'s to rounding (~1e-15 of the rate)."""
        row = streamed_row(rate_dps)
        with self.lock:
            s = self.state
            if isinstance(s.rate, QueuedRates):
                s.rate.add(output_samples.first_not_due(s, self.clock.now_ns()), row)
                return
            self._rate_due()
            s.invalidate()
            s.rate = QueuedRates(s.k + 1, row)

    def _rate_due(self) -> None:
        """The samples due before a new true rate; those a failing rate function could not
        produce come from the new one (it is being replaced)."""
        try:
            self._now()
        except Exception:
            if not self.state.rate.failed:
                raise

    def _apply_true_rate(self, rate: Any, sample_rate_hz: float | None) -> None:
        s = self.state
        first_ns = s.next_ns if s.next_ns < NEVER else self.clock.now_ns()
        source = true_rate_source(rate, sample_rate_hz, first_k=s.k + 1, first_ns=first_ns)
        s.invalidate()
        s.rate = source

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
        # directly (VirtualClock.advance_ns and now_ns inlined, tools/bench_fake_smbus.py),
        # and a front end's fast path logs its ``ns`` (the same time as ``time``, no float made)
        self.virtual_clock = clock if type(clock) is VirtualClock and clock.lock is self.lock else None

    @property
    def time(self) -> float:
        """The chip's current time in seconds (every bus transaction logs it)."""
        clock = self.virtual_clock
        return clock.ns / NS_PER_S if clock is not None else self.clock.now()

    @property
    def power_mode(self) -> str:
        return self.state.power_mode

    @property
    def odr_hz(self) -> int:
        return self.state.odr

    @property
    def sensitivity(self) -> float:
        """LSB per deg/s of the current range."""
        return self.state.sensitivity

    @property
    def sensitivity_table(self) -> tuple[float, ...]:
        return self.state.sensitivity_table

    @property
    def int1(self) -> bool:
        """INT1 asserted (logical state, before level and output type)."""
        with self.lock:
            return regmap.pins(self.state, self._now())[0]

    @property
    def int2(self) -> bool:
        with self.lock:
            return regmap.pins(self.state, self._now())[1]

    def int_pin_level(self, pin: int) -> int:
        """Electrical level 0/1 of INT1 or INT2 for a push-pull output (INT_EN_1 lvl bit)."""
        with self.lock:
            return regmap.pin_level(self.state, pin, self._now())

    def next_pin_change_ns(self) -> int | None:
        """The earliest time (ns on the chip's clock) INT1 or INT2 may change with no bus
        access, or None when they hold until one (regmap.next_pin_change)."""
        with self.lock:
            return regmap.next_pin_change(self.state, self._now())

    def offsets_lsb(self) -> tuple[int, int, int]:
        """The three 12-bit offsets of OFC1..OFC4 and TRIM_GP0 (4.24)."""
        return offsets.offsets_from(self.state.regs)

    @property
    def offset_lsb_dps(self) -> float:
        """deg/s per offset LSB: one count of the +-2000 deg/s range (6.9, unconfirmed)."""
        return self.state.offset_lsb_dps

    @property
    def nvm_image(self) -> bytes:
        return bytes(self.state.nvm.image)

    # ------------------------------------------------------------------ primitives

    def write(self, reg: int, data: bytes | Sequence[int]) -> None:
        """One bus write transaction of ``data`` starting at ``reg`` (auto-increment)."""
        reg = self._check_reg(reg)
        payload = self._check_data(data)
        with self.lock:
            now = self._now()
            self._pointer = register_access.write_burst(self.state, reg, payload, now)

    def read(self, reg: int, n: int = 1) -> bytes:
        """One bus read transaction of ``n`` bytes from ``reg`` with every side effect."""
        lock = self.lock  # acquire/try/finally: half the cost of ``with`` on CPython 3.11
        lock.acquire()  # (75 against 150 ns, tools/bench_fake_smbus.py's hot path)
        try:
            s = self.state
            clock = self.virtual_clock
            now = clock.ns if clock is not None else self._clock.now_ns()
            if now >= s.next_ns:
                catch_up(s, now)
            if reg == _RATE_X_LSB and n == 6 and reg.__class__ is int:  # fast path: X, Y, Z
                if s.latched:
                    s.msb_latch = [None, None, None]
                    s.latched = False
                s.data_ready_pending = False
                self._pointer = _RATE_END
                return s.cur
            reg = self._check_reg(reg)
            n = self._check_count(n)
            data, self._pointer = register_access.read_burst(s, reg, n, now)
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
                self._pointer = register_access.write_burst(self.state, payload[0], payload[1:], now)

    def i2c_read(self, n: int) -> bytes:
        """I2C read of ``n`` bytes from the current register pointer."""
        n = self._check_count(n)
        with self.lock:
            now = self._now()
            data, self._pointer = register_access.read_burst(self.state, self._pointer, n, now)
            return data

    @property
    def pointer(self) -> int:
        """The I2C register pointer."""
        return self._pointer

    def peek(self, reg: int) -> int:
        """Register content without side effects (no MSB latch, no FIFO pop)."""
        reg = self._check_reg(reg)
        with self.lock:
            now = self._now()
            return register_access.peek_reg(self.state, reg, now)

    def dump(self) -> bytes:
        """The 64 registers 0x00..0x3F, without side effects."""
        with self.lock:
            now = self._now()
            s = self.state
            return bytes(register_access.peek_reg(s, a, now) for a in range(FIRST_OUTSIDE_MAP))

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
            s = self.state
            clock = self.virtual_clock
            if clock is not None:  # VirtualClock.advance_ns inlined: its lock is held
                now = clock.ns = clock.ns + ns
            else:
                now = self._clock.advance_ns(ns)
            t = s.next_ns
            if now < t:
                return
            period = s.period_ns
            if now >= t + period or not s.plain or self.sample_hooks or self.truth_hooks:
                catch_up(s, now)
                return
            k = s.k + 1
            b = s.block
            if b is None or k >= b.end:
                b = s.block_for(k)
            samples = b.samples
            if samples is None:
                samples = b.cut_samples()
            s.cur = samples[k - b.k0]
            s.k = k
            s.last_sample_ns = t
            s.next_ns = t + period
            s.data_ready_pending = True
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
            now = self._now()
            register_access.poke_reg(self.state, reg, value, now)

    def power_on_reset(self) -> None:
        """Every register back to reset values, as after a brown-out; data after start-up."""
        with self.lock:
            now = self._now()
            self.state.reset(now, powered=False)
            self._pointer = 0

    def soft_reset(self) -> None:
        """The effect of writing 0xB6 to BGW_SOFTRESET (6.6)."""
        self.write(_BGW_SOFTRESET, bytes((regmap.SOFTRESET_KEY,)))

    _check_reg = staticmethod(contract.check_register)
    _check_count = staticmethod(contract.check_count)
    _check_data = staticmethod(contract.check_data)

    # ------------------------------------------------------------------ catch-up

    def _now(self) -> int:
        """The time now in ns, every sample due by then produced (between transactions)."""
        now = self._clock.now_ns()
        s = self.state
        if now >= s.next_ns:
            catch_up(s, now)
        return now

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(address=0x{self.address:02X}, t={self.clock.now():.6f} s, "
                f"mode={self.power_mode}, odr={self.state.odr} Hz)")
