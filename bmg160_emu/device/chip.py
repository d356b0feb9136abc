"""``BMG160``: the register-level model of the Bosch BMG160 gyroscope.

Front ends (I2C, SMBus, SPI, Linux) reach the chip only through its primitives
(``write``, ``read``, ``i2c_write``, ``i2c_read``, ``peek``, ``dump``), see
docs/architecture.md. Section numbers refer to the register specification.

Data path per output sample (6.1):
    true body rate -> mounting, scale factor, misalignment -> chip low-pass for BW
    -> + noise (output-referred) -> + offset registers (6.9) -> sample hooks
    -> x sensitivity(RANGE) -> round, saturate to int16 -> RATE registers, FIFO, engines.

Speed: the data path is computed ahead in blocks (noise drawn in blocks, filter and scaling
vectorised) and thrown away from the current sample on when the configuration changes;
the per-sample engines (FIFO storage, any-motion, high-rate, fast offset) run only when
enabled. Time is integer nanoseconds: sample k of a run is at ``anchor + k * period``.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from bmg160_emu.clock import NS_PER_S, RealTimeClock, VirtualClock, seconds_to_ns
from bmg160_emu.device import fifo as fifo_mod
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.contract import check_count, check_data, check_register
from bmg160_emu.device.interrupts import AnyMotion, HighRate, InterruptStatus, latch_hold_ns
from bmg160_emu.device.lowpass import LowPass
from bmg160_emu.device.registers import (
    FIRST_OUTSIDE_MAP,
    NVM_ADDRESSES,
    RESET_VALUES,
    WRITE_MASKS,
)

log = logging.getLogger(__name__)

NEVER = 1 << 62  # "no sample due": compared with clock times in ns
NORMAL, DEEP_SUSPEND, SUSPEND, FAST_POWER_UP, POWER_SAVE = (
    "normal", "deep suspend", "suspend", "fast power-up", "advanced power saving")
_SAMPLING_MODES = (NORMAL, POWER_SAVE)  # 6.7: power saving samples as normal (unconfirmed)
_BLOCK = 1024  # samples computed ahead
_MAX_BLOCK = 65536  # when catching up a long gap
_NOISE_CHUNK = 256  # least noise drawn at once (the generator buffers small requests)
VALID_ADDRESSES = (0x68, 0x69)

# Register addresses used by name below (spec 3).
RANGE, BW, LPM1, LPM2, RATE_HBW, BGW_SOFTRESET = 0x0F, 0x10, 0x11, 0x12, 0x13, 0x14
INT_EN_0, INT_EN_1, INT_MAP_0, INT_MAP_1, INT_MAP_2 = 0x15, 0x16, 0x17, 0x18, 0x19
INT_DATA_SRC, ANY_TH, ANY_EN, FIFO_WM_EN, INT_RST_LATCH = 0x1A, 0x1B, 0x1C, 0x1E, 0x21
A_FOC, TRIM_NVM_CTRL, BIST, FIFO_CONFIG_0, FIFO_CONFIG_1, FIFO_DATA = (
    0x32, 0x33, 0x3C, 0x3D, 0x3E, 0x3F)
OFC1, TRIM_GP0 = 0x36, 0x3A
_ENGINE_REGS = frozenset({INT_EN_0, ANY_EN, 0x22, 0x24, 0x26, FIFO_WM_EN})


def power_mode(lpm1: int, lpm2: int) -> str:
    """Power mode from LPM1/LPM2 by the physical priority rule of spec 6.7 (unconfirmed)."""
    if lpm1 & 0x20:
        return DEEP_SUSPEND
    if lpm1 & 0x80:
        return FAST_POWER_UP if lpm2 & 0x80 else SUSPEND
    if lpm2 & 0x40:
        return POWER_SAVE
    return NORMAL


def _sign_extend12(value: int) -> int:
    return value - 4096 if value & 0x800 else value


def _as_matrix(value: Any, name: str) -> np.ndarray:
    m = np.asarray(value, dtype=float)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise ValueError(f"{name} must be a finite 3x3 matrix")
    return m


class _Block:
    """The data path for samples k0 .. k0 + n - 1, computed ahead."""

    __slots__ = ("body", "counts_f", "counts_u", "dps_f", "dps_u", "end", "k0", "n",
                 "rate_bytes", "x", "y", "zi0")
    k0: int
    n: int
    end: int
    body: np.ndarray  # true body rate, deg/s
    x: np.ndarray  # sensor-frame rate before the filter
    y: np.ndarray  # filtered
    zi0: np.ndarray  # filter state before the first sample
    dps_f: np.ndarray  # filtered + noise + offset, deg/s
    dps_u: np.ndarray  # unfiltered + noise + offset, deg/s
    counts_f: np.ndarray
    counts_u: np.ndarray
    rate_bytes: bytes  # the selected counts, 6 bytes per sample


class BMG160:
    """A BMG160 gyroscope at register level.

    ``seed`` with ``address`` (0x68/0x69) seeds the noise, so two chips sharing a master
    seed have independent noise. ``noise=False`` gives a noiseless chip. ``clock`` is a
    new ``VirtualClock`` unless one is passed (several chips can share it) or a
    ``RealTimeClock``. ``sensitivity`` is "binary" (32768/FS, default), "nominal" or five
    LSB/(deg/s) figures for RANGE codes 0..4. ``hold_data_int=True`` holds data_int until
    the rate registers are read (an emulator convenience, not chip behaviour). ``strict``
    logs questionable driver behaviour to ``strict_log`` and the ``bmg160_emu.device.chip`` logger.
    """

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
    ) -> None:
        if address not in VALID_ADDRESSES:
            raise ValueError(f"BMG160 address must be 0x68 or 0x69, not {address!r}")
        if noise_mode not in ("physical", "paper"):
            raise ValueError(f"noise_mode must be 'physical' or 'paper', not {noise_mode!r}")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
            raise TypeError(f"seed must be an int or None, not {type(seed).__name__}")
        self.address = address
        self.lock = threading.RLock()
        self.clock = VirtualClock() if clock is None else clock
        if not hasattr(self.clock, "now_ns"):
            raise TypeError("clock must be a VirtualClock or RealTimeClock")
        self.sample_hooks: list[Callable[..., Any]] = []
        self.truth_hooks: list[Callable[..., Any]] = []
        self.strict = bool(strict)
        self.strict_log: list[str] = []
        self.hold_data_int = bool(hold_data_int)
        self.inject_bist_failure = False
        self._startup_ns = seconds_to_ns(startup_time_s)
        self._sensitivity = self._sensitivity_table(sensitivity)
        self._transform = self._build_transform(mounting, scale_factor, misalignment)
        self.seed = seed
        self._noise_gen = None
        if noise:
            from bmg160_emu.noise import NoiseGenerator

            self._noise_gen = NoiseGenerator(
                profile=profile, rate_hz=2000.0, seed=self._noise_seed(seed, address),
                mode=noise_mode)
        self._noise_buf = np.zeros((0, 3))
        self._noise_k0 = 0
        # (sample index, generator checkpoint) before each draw: on an ODR change the generator
        # goes back to the first unused sample, so the noise does not depend on how far ahead
        # the data path had computed (i.e. on the driver's polling pattern)
        self._noise_marks: list[tuple[int, Any]] = []
        self.set_temperature(temperature_c)
        if nvm_image is None:
            nvm_image = choice.NVM_DEFAULT_IMAGE
        if len(nvm_image) != len(NVM_ADDRESSES):
            raise ValueError(f"nvm_image must be {len(NVM_ADDRESSES)} bytes (0x36..0x3B)")
        if not 0 <= nvm_remain <= 15:
            raise ValueError("nvm_remain must be 0..15")
        self._nvm = bytearray(nvm_image)
        self._nvm_remain = nvm_remain
        self._k = -1  # index of the last sample produced
        self._block: _Block | None = None
        self._rate_kind = "constant"
        self._rate_const = np.zeros(3)
        self._rate_func: Callable[[float], Any] = lambda t: (0.0, 0.0, 0.0)
        self._rate_func_failed = False
        self._rate_samples = np.zeros((1, 3))
        self._rate_samples_t0 = 0
        self._rate_samples_hz: float | None = None
        self._rate_samples_k0 = 0
        self._pointer = 0
        self._next_ns = NEVER
        self._emitting = False
        self._cur = bytes(6)
        self._latched = False
        self._msb_latch: list[int | None] = [None, None, None]
        self._foc: dict[str, Any] | None = None
        self._bist_start: int | None = None
        self._temp_frozen: tuple[int, int] | None = None  # (raw, last sample ns) when stopped
        self._reset_state(self.clock.now_ns(), powered=choice.POWERED_UP_AT_CONSTRUCTION)
        self._apply_true_rate(true_rate, None)

    # ------------------------------------------------------------------ configuration

    @staticmethod
    def _sensitivity_table(sensitivity: str | Sequence[float]) -> tuple[float, ...]:
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

    @staticmethod
    def _build_transform(mounting: Any, scale_factor: Any, misalignment: Any) -> np.ndarray | None:
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
            if sf.shape != (3,) or not np.all(np.isfinite(sf)):
                raise ValueError("scale_factor must be 3 finite fractional errors")
            m = np.diag(1.0 + sf) @ m
        if misalignment is not None:
            mis = _as_matrix(misalignment, "misalignment")
            m = (np.eye(3) + mis - np.diag(np.diag(mis))) @ m
        return m

    @staticmethod
    def _noise_seed(seed: int | None, address: int) -> int | None:
        if seed is None:
            return None
        return int(np.random.SeedSequence([int(seed), address]).generate_state(1, np.uint64)[0])

    def set_temperature(self, temperature_c: float | Callable[[float], float]) -> None:
        """Die temperature in deg C: a constant or a callable of time in seconds."""
        if not callable(temperature_c):
            value = float(temperature_c)
            if not math.isfinite(value):
                raise ValueError("temperature must be finite")
        with self.lock:
            self._temperature = temperature_c

    def set_true_rate(self, rate: Any, *, sample_rate_hz: float | None = None) -> None:
        """True body angular rate in deg/s: a 3-tuple, a callable ``t -> 3-vector`` or an
        ``(n, 3)`` array of samples. Samples are taken one per output sample from the next
        one on (or at ``sample_rate_hz``, held between rows); the last row then holds."""
        with self.lock:
            try:
                self._catch_up(self.clock.now_ns())
            except Exception:
                if not (self._rate_kind == "callable" and self._rate_func_failed):
                    raise
                # the failing function is being replaced: the samples it could not produce
                # come from the new true rate
            self._apply_true_rate(rate, sample_rate_hz)

    def _apply_true_rate(self, rate: Any, sample_rate_hz: float | None) -> None:
        if callable(rate):
            self._invalidate()
            self._rate_kind, self._rate_func = "callable", rate
            return
        try:
            arr = np.asarray(rate, dtype=float)
        except (TypeError, ValueError):
            raise ValueError("true rate must be 3 numbers in deg/s, a callable of t or (n, 3) "
                             f"samples, not {rate!r}") from None
        if arr.shape == (3,):
            if not np.all(np.isfinite(arr)):
                raise ValueError("true rate must be finite")
            self._invalidate()
            self._rate_kind, self._rate_const = "constant", arr.copy()
        elif arr.ndim == 2 and arr.shape[1] == 3 and arr.shape[0] >= 1:
            if not np.all(np.isfinite(arr)):
                raise ValueError("true rate samples must be finite")
            if sample_rate_hz is not None and not sample_rate_hz > 0:
                raise ValueError("sample_rate_hz must be positive")
            self._invalidate()
            self._rate_kind, self._rate_samples = "samples", arr.copy()
            self._rate_samples_k0 = self._k + 1
            self._rate_samples_t0 = self._next_ns if self._next_ns < NEVER else self.clock.now_ns()
            self._rate_samples_hz = sample_rate_hz
        else:
            raise ValueError("true rate must be 3 numbers, a callable of t or (n, 3) samples")

    # ------------------------------------------------------------------ properties

    @property
    def time(self) -> float:
        """The chip's current time in seconds."""
        return self.clock.now()

    @property
    def power_mode(self) -> str:
        return power_mode(self._regs[LPM1], self._regs[LPM2])

    @property
    def odr_hz(self) -> int:
        return self._odr

    @property
    def sensitivity(self) -> float:
        """LSB per deg/s of the current range."""
        return self._sens_now()

    @property
    def sensitivity_table(self) -> tuple[float, ...]:
        return self._sensitivity

    @property
    def int1(self) -> bool:
        """INT1 asserted (logical state, before level and output type)."""
        with self.lock:
            now = self._now()
            return self._pins(now)[0]

    @property
    def int2(self) -> bool:
        with self.lock:
            now = self._now()
            return self._pins(now)[1]

    def int_pin_level(self, pin: int) -> int:
        """Electrical level 0/1 of INT1 or INT2 for a push-pull output (INT_EN_1 lvl bit)."""
        if pin not in (1, 2):
            raise ValueError("pin must be 1 or 2")
        active = self.int1 if pin == 1 else self.int2
        active_high = self._regs[INT_EN_1] >> (0 if pin == 1 else 2) & 1
        return int(active == bool(active_high))

    def offsets_lsb(self) -> tuple[int, int, int]:
        """The three 12-bit offsets of OFC1..OFC4 and TRIM_GP0 (4.24)."""
        r = self._regs
        x = r[0x37] << 4 | (r[OFC1] >> 6 & 3) << 2 | (r[TRIM_GP0] >> 2 & 3)
        y = r[0x38] << 4 | (r[OFC1] >> 3 & 7) << 1 | (r[TRIM_GP0] >> 1 & 1)
        z = r[0x39] << 4 | (r[OFC1] & 7) << 1 | (r[TRIM_GP0] & 1)
        return _sign_extend12(x), _sign_extend12(y), _sign_extend12(z)

    def _set_offsets_lsb(self, offsets: Sequence[int | None]) -> None:
        r = self._regs
        for axis, value in enumerate(offsets):
            if value is None:
                continue
            v = int(value) & 0xFFF
            r[0x37 + axis] = v >> 4
            if axis == 0:
                r[OFC1] = (r[OFC1] & 0x3F) | (v >> 2 & 3) << 6
                r[TRIM_GP0] = (r[TRIM_GP0] & 0xF3) | (v & 3) << 2
            elif axis == 1:
                r[OFC1] = (r[OFC1] & 0xC7) | (v >> 1 & 7) << 3
                r[TRIM_GP0] = (r[TRIM_GP0] & 0xFD) | (v & 1) << 1
            else:
                r[OFC1] = (r[OFC1] & 0xF8) | (v >> 1 & 7)
                r[TRIM_GP0] = (r[TRIM_GP0] & 0xFE) | (v & 1)

    @property
    def offset_lsb_dps(self) -> float:
        """deg/s per offset LSB: one count of the +-2000 deg/s range (6.9, unconfirmed)."""
        return 1.0 / self._sensitivity[choice.OFFSET_LSB_RANGE_CODE]

    @property
    def nvm_image(self) -> bytes:
        return bytes(self._nvm)

    # ------------------------------------------------------------------ primitives

    def write(self, reg: int, data: bytes | Sequence[int]) -> None:
        """One bus write transaction of ``data`` starting at ``reg`` (auto-increment)."""
        reg = self._check_reg(reg)
        payload = self._check_data(data)
        with self.lock:
            now = self._now()
            self._pointer = self._write_burst(reg, payload, now)

    def read(self, reg: int, n: int = 1) -> bytes:
        """One bus read transaction of ``n`` bytes from ``reg`` with every side effect."""
        with self.lock:
            now = self.clock.now_ns()
            if now >= self._next_ns:
                self._catch_up(now)
            if reg == 2 and n == 6 and reg.__class__ is int:  # fast path: X, Y, Z burst
                if self._latched:
                    self._msb_latch = [None, None, None]
                    self._latched = False
                self._data_ready_pending = False
                self._pointer = 8
                return self._cur
            reg = self._check_reg(reg)
            n = self._check_count(n)
            data, self._pointer = self._read_burst(reg, n, now)
            return data

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
                self._pointer = self._write_burst(payload[0], payload[1:], now)

    def i2c_read(self, n: int) -> bytes:
        """I2C read of ``n`` bytes from the current register pointer."""
        n = self._check_count(n)
        with self.lock:
            now = self._now()
            data, self._pointer = self._read_burst(self._pointer, n, now)
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
            return self._peek_reg(reg, now)

    def dump(self) -> bytes:
        """The 64 registers 0x00..0x3F, without side effects."""
        with self.lock:
            now = self._now()
            return bytes(self._peek_reg(a, now) for a in range(FIRST_OUTSIDE_MAP))

    def advance(self, seconds: float) -> None:
        """Advance the clock; the chip produces exactly one sample per output period."""
        try:
            ns = round(seconds * 1e9)
        except (TypeError, ValueError, OverflowError):
            ns = seconds_to_ns(seconds)  # raises the clear error
        if ns < 0:
            ns = seconds_to_ns(seconds)
        with self.lock:
            now = self.clock.advance_ns(ns)
            if now >= self._next_ns:
                self._catch_up(now)

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
            if 2 <= reg <= 7:
                cur = bytearray(self._cur)
                cur[reg - 2] = value
                self._cur = bytes(cur)
                return
            mode = self.power_mode
            old = self._regs[reg]
            self._regs[reg] = value
            if reg == BW and (old ^ value) & 7:
                self._change_bandwidth()
            elif reg in (LPM1, LPM2):
                self._power_transition(mode, reg, value, now)
            elif reg in (RANGE, RATE_HBW) or OFC1 <= reg <= TRIM_GP0:
                self._invalidate()
            if reg in _ENGINE_REGS or reg == FIFO_CONFIG_1:
                self._engine_config_changed(now)

    def power_on_reset(self) -> None:
        """Every register back to reset values, as after a brown-out; data after start-up."""
        with self.lock:
            now = self._now()
            self._reset_state(now, powered=False)
            self._pointer = 0

    def soft_reset(self) -> None:
        """The effect of writing 0xB6 to BGW_SOFTRESET (6.6)."""
        self.write(BGW_SOFTRESET, b"\xb6")

    # ------------------------------------------------------------------ argument checks

    _check_reg = staticmethod(check_register)
    _check_count = staticmethod(check_count)
    _check_data = staticmethod(check_data)

    def _strict(self, message: str) -> None:
        if self.strict:
            self.strict_log.append(message)
            log.warning("BMG160 0x%02X: %s", self.address, message)

    # ------------------------------------------------------------------ reset

    def _reset_state(self, now: int, *, powered: bool) -> None:
        """Soft reset, power-on reset and leaving deep suspend (6.6, 6.7)."""
        self._block = None
        self._regs = bytearray(RESET_VALUES)
        for i, addr in enumerate(NVM_ADDRESSES):
            self._regs[addr] = self._nvm[i]
        self._nvm_busy_until = -1
        self._cur = bytes(6)
        self._have_sample = False
        self._last_sample_ns = -NEVER
        self._sample_seq = 0
        self._data_ready_pending = False
        self._msb_latch = [None, None, None]
        self._latched = False
        self._fifo = fifo_mod.Fifo()
        self._bypass_seq = 0
        self._status = {name: InterruptStatus()
                        for name in ("any", "high", "fifo", "fast_offset", "auto_offset")}
        self._any = AnyMotion()
        self._high = HighRate()
        self._int_status_2 = 0
        self._int_status_3 = 0
        self._bist_start = None
        self._foc = None
        self._configure_data_path(restart=True)
        self._update_engine_flags()
        self._start_sampling(now if powered else now + self._startup_ns)

    def _start_sampling(self, first_ns: int) -> None:
        self._invalidate()
        self._anchor_ns = first_ns
        self._anchor_k = self._k + 1
        self._next_ns = first_ns
        self._data_start_ns = first_ns
        self._filter_restart = True

    def _stop_sampling(self) -> None:
        self._invalidate()
        self._next_ns = NEVER
        # 5.2: TEMP keeps its last conversion until the next sample (frozen while not sampling)
        self._temp_frozen = (self._temp_raw(), self._last_sample_ns)

    # ------------------------------------------------------------------ data path

    def _range_sensitivity(self, range_reg: int) -> float:
        code = range_reg & 7
        if code > 4:
            code = choice.RESERVED_RANGE_AS_CODE
        return self._sensitivity[code]

    def _sens_now(self) -> float:
        return self._range_sensitivity(self._regs[RANGE])

    def _configure_data_path(self, *, restart: bool = False) -> None:
        """Set ODR and filter from BW; keep the sample schedule and noise realisation."""
        odr, bandwidth = choice.BANDWIDTHS[self._regs[BW] & 7]
        old_odr = getattr(self, "_odr", None)
        self._odr = odr
        self._period_ns = NS_PER_S // odr
        self._filter = LowPass(odr, bandwidth)
        if old_odr != odr:
            used_end = self._k + 1  # index of the first sample not yet produced
            keep = max(used_end - self._noise_k0, 0)
            if self._noise_gen is not None:
                if self._noise_k0 + len(self._noise_buf) > used_end:
                    self._rewind_noise(used_end)
                self._noise_marks = []
                self._noise_gen.set_rate(float(odr))
            self._noise_buf = self._noise_buf[:keep]
        if restart:
            self._filter_restart = True

    def _invalidate(self) -> None:
        """Drop the computed-ahead samples after the current one (configuration changed)."""
        b = self._block
        if b is None:
            return
        j = self._k - b.k0
        if j >= 0:
            _, self._filter.state = self._filter.run(b.x[: j + 1], b.zi0)
            self._last_y = b.y[j].copy()
        else:
            self._filter.state = b.zi0
        self._block = None

    def _change_bandwidth(self) -> None:
        self._invalidate()
        last = getattr(self, "_last_y", None)
        old_odr = self._odr
        self._configure_data_path()
        if last is not None and not self._filter_restart:
            self._filter.restart(last)
        else:
            self._filter_restart = True
        if self._odr != old_odr and self._next_ns < NEVER:
            # next sample one new period after the last one (or the pending first one)
            if self._have_sample and self._last_sample_ns >= self._data_start_ns:
                base = self._last_sample_ns
                self._next_ns = base + self._period_ns
            self._anchor_ns, self._anchor_k = self._next_ns, self._k + 1

    def _true_body(self, k0: int, n: int) -> np.ndarray:
        kind = self._rate_kind
        if kind == "constant":
            return np.broadcast_to(self._rate_const, (n, 3))
        times_ns = self._anchor_ns + (np.arange(k0, k0 + n) - self._anchor_k) * self._period_ns
        if kind == "callable":
            out = np.empty((n, 3))
            self._rate_func_failed = True  # until it has served the block (set_true_rate)
            for i, t in enumerate(times_ns / NS_PER_S):
                value = self._rate_func(float(t))
                try:
                    row = np.asarray(value, dtype=float)
                except (TypeError, ValueError) as exc:
                    raise ValueError(f"the true-rate function must return 3 numbers in deg/s: "
                                     f"at t = {float(t):g} s {exc}") from None
                if row.size != 3:
                    raise ValueError(f"the true-rate function must return 3 numbers in deg/s, "
                                     f"got {row.size} at t = {float(t):g} s")
                out[i] = row.reshape(3)
            if not np.all(np.isfinite(out)):
                raise ValueError("the true-rate function returned a non-finite value")
            self._rate_func_failed = False
            return out
        samples = self._rate_samples
        if self._rate_samples_hz is None:
            rows = np.arange(k0, k0 + n) - self._rate_samples_k0
        else:
            rows = np.floor((times_ns - self._rate_samples_t0) / NS_PER_S
                            * self._rate_samples_hz).astype(np.int64)
        return samples[np.clip(rows, 0, len(samples) - 1)]

    def _noise_for(self, k0: int, n: int) -> np.ndarray:
        if self._noise_gen is None:
            return np.zeros((n, 3))
        start = k0 - self._noise_k0
        if start < 0 or start > len(self._noise_buf):
            self._noise_buf, self._noise_k0, start = np.zeros((0, 3)), k0, 0
            self._noise_marks = []
        elif start > 0:
            self._noise_buf, self._noise_k0, start = self._noise_buf[start:], k0, 0
            marks = self._noise_marks
            first = 0
            while first + 1 < len(marks) and marks[first + 1][0] <= k0:
                first += 1
            del marks[:first]
        missing = n - len(self._noise_buf)
        if missing > 0:
            self._noise_marks.append(
                (self._noise_k0 + len(self._noise_buf), self._noise_gen.checkpoint()))
            fresh = np.asarray(self._noise_gen.generate(max(missing, _NOISE_CHUNK)), dtype=float)
            self._noise_buf = np.concatenate([self._noise_buf, fresh.reshape(-1, 3)])
        return self._noise_buf[:n]

    def _rewind_noise(self, used_end: int) -> None:
        """Put the noise generator back at sample ``used_end`` (noise drawn ahead unused)."""
        gen = self._noise_gen
        assert gen is not None
        marks = [m for m in self._noise_marks if m[0] <= used_end]
        if not marks:
            return  # no checkpoint before it: continue from where the generator stands
        index, checkpoint = marks[-1]
        gen.restore(checkpoint)
        if used_end > index:
            gen.generate(used_end - index)

    def _build_block(self, k0: int, n: int) -> _Block:
        body = self._true_body(k0, n)
        x = body if self._transform is None else body @ self._transform.T
        filt = self._filter
        if self._filter_restart:
            filt.restart(x[0])
            self._filter_restart = False
        elif self._rate_kind == "constant":
            filt.rebase_if_settled(x[0])
        b = _Block()
        b.k0, b.n, b.end = k0, n, k0 + n
        b.body, b.x, b.zi0 = body, x, filt.state
        b.y, filt.state = filt.run(x)
        noise = self._noise_for(k0, n)
        offset = np.asarray(self.offsets_lsb(), dtype=float) * self.offset_lsb_dps
        if offset.any():
            noise = noise + offset
        if self._noise_gen is None and not offset.any():
            b.dps_f, b.dps_u = b.y, x
        else:
            b.dps_f, b.dps_u = b.y + noise, x + noise
        sens = self._sens_now()
        b.counts_f = np.clip(np.rint(b.dps_f * sens), -32768, 32767).astype(np.int16)
        b.counts_u = np.clip(np.rint(b.dps_u * sens), -32768, 32767).astype(np.int16)
        sel = b.counts_u if self._regs[RATE_HBW] & 0x80 else b.counts_f
        b.rate_bytes = sel.astype("<i2").tobytes()
        return b

    def _block_for(self, k: int) -> _Block:
        b = self._block
        if b is None or k >= b.end or k < b.k0:
            b = self._block = self._build_block(k, _BLOCK)
        return b

    # ------------------------------------------------------------------ sampling

    def _now(self) -> int:
        now = self.clock.now_ns()
        if now >= self._next_ns:
            self._catch_up(now)
        return now

    def _catch_up(self, now: int) -> None:
        """Produce every sample due by ``now`` (between transactions, never inside one)."""
        while now >= self._next_ns:
            if self._per_sample or self.sample_hooks or self.truth_hooks:
                if self._emitting:  # a hook called a primitive: finish this sample first
                    return
                self._emitting = True
                try:
                    self._emit_one()
                finally:
                    self._emitting = False
                continue
            t = self._next_ns
            period = self._period_ns
            if now < t + period and not self._fifo_store_mode and not self._fifo_int_on:
                # fast path: exactly one new sample, nothing stored per sample
                k = self._k + 1
                b = self._block
                if b is None or k >= b.end:
                    b = self._block_for(k)
                i = 6 * (k - b.k0)
                self._cur = b.rate_bytes[i:i + 6]
                self._k = k
                self._last_sample_ns = t
                self._next_ns = t + period
                self._have_sample = True
                self._sample_seq += 1
                self._data_ready_pending = True
                return
            self._emit_batch((now - t) // period + 1)

    def _emit_batch(self, n: int) -> None:
        """n samples with no per-sample engine: only the last one and the FIFO matter."""
        k_first = self._k + 1
        k_last = self._k + n
        fifo_mode = self._fifo_store_mode
        wanted: range | None = None
        if fifo_mode:
            if fifo_mode == fifo_mod.FIFO:
                room = max(self._fifo.capacity - self._fifo.count, 0)
                wanted = range(k_first, k_first + min(n, room))
            else:
                wanted = range(max(k_first, k_last - self._fifo.capacity + 1), k_last + 1)
            frames: list[bytes] = []
            axis, tag = self._frame_format()
        k = k_first
        while True:
            b = self._block
            if b is None or k >= b.end or k < b.k0:
                size = _BLOCK if k_last - k < _BLOCK else min(k_last - k + 1, _MAX_BLOCK)
                b = self._block = self._build_block(k, size)
            seg_end = min(b.end, k_last + 1)
            if wanted is not None and wanted:
                lo, hi = max(k, wanted.start), min(seg_end, wanted.stop)
                rb = b.rate_bytes
                for kk in range(lo, hi):
                    i = 6 * (kk - b.k0)
                    frames.append(rb[i + axis.start:i + axis.stop] + tag)
            if seg_end > k_last:
                break
            self._k = seg_end - 1
            k = seg_end
        i = 6 * (k_last - b.k0)
        self._cur = b.rate_bytes[i:i + 6]
        self._k = k_last
        self._last_sample_ns = self._next_ns + (n - 1) * self._period_ns
        self._next_ns = self._last_sample_ns + self._period_ns
        self._have_sample = True
        self._sample_seq += n
        self._data_ready_pending = True
        if fifo_mode:
            self._fifo.push_many(frames, fifo_mode, total=n)
        if self._fifo_int_on:
            self._update_fifo_int(self._last_sample_ns)

    def _emit_one(self) -> None:
        k = self._k + 1
        b = self._block_for(k)
        i = k - b.k0
        t_ns = self._next_ns
        t_s = t_ns / NS_PER_S
        self._k = k
        self._next_ns = t_ns + self._period_ns
        for hook in list(self.truth_hooks):
            hook(self, t_s, np.array(b.body[i], dtype=float))
        high_bw = self._regs[RATE_HBW] & 0x80
        rate_bytes = b.rate_bytes[6 * i:6 * i + 6]
        counts_f = b.counts_f[i]
        counts_u = b.counts_u[i]
        dps_pre = None
        if self.sample_hooks:
            rate: np.ndarray = np.array(b.dps_u[i] if high_bw else b.dps_f[i], dtype=np.float64)
            for hook in list(self.sample_hooks):
                result = hook(self, t_s, rate)
                if result is None:
                    return  # a lost sample: no data-ready, no register update
                rate = np.asarray(result, dtype=np.float64)
                if rate.size != 3:
                    raise ValueError(f"sample hook {hook!r} must return 3 numbers in deg/s or "
                                     f"None, got {rate.size} at t = {t_s:g} s")
                rate = rate.reshape(3)
            counts = np.clip(np.rint(rate * self._sens_now()), -32768, 32767).astype(np.int16)
            rate_bytes = counts.astype("<i2").tobytes()
            counts_f = counts_u = counts
            dps_pre = rate
        self._cur = rate_bytes
        self._last_sample_ns = t_ns
        self._have_sample = True
        self._sample_seq += 1
        self._data_ready_pending = True
        hold = latch_hold_ns(self._regs[INT_RST_LATCH])
        if self._any_axes:
            src = counts_u if self._regs[INT_DATA_SRC] & 0x02 else counts_f
            r = self._regs
            rose = self._any.step(
                (int(src[0]), int(src[1]), int(src[2])), self._any_axes, (1 + (r[ANY_TH] & 0x7F)) * 16,
                4 * ((r[ANY_EN] >> 4 & 3) + 1),
                -(-self._odr // choice.ANY_MOTION_MAX_RATE_HZ))
            if rose:
                self._int_status_2 = self._any.status_byte()
            self._status["any"].update(self._any.active, t_ns, hold)
        if self._high_axes:
            src = counts_u if self._regs[INT_DATA_SRC] & 0x08 else counts_f
            r = self._regs
            ths, hys, durs = [], [], []
            for axis in range(3):
                th = r[0x22 + 2 * axis]
                ths.append((255 + 256 * (th >> 1 & 0x1F)) * 4)
                hys.append((255 + 256 * (th >> 6)) * 4)
                durs.append(-(-(1 + r[0x23 + 2 * axis]) * 25 * self._odr // 10000))
            rose = self._high.step((int(src[0]), int(src[1]), int(src[2])), self._high_axes,
                                   ths, hys, durs)
            if rose:
                self._int_status_3 = self._high.status_byte()
            self._status["high"].update(self._high.active, t_ns, hold)
        foc = self._foc
        if foc is not None:
            if dps_pre is None:
                dps_pre = b.dps_u[i] if foc["unfilt"] else b.dps_f[i]
            offset = np.asarray(self.offsets_lsb(), dtype=float) * self.offset_lsb_dps
            foc["sum"] += np.asarray(dps_pre, dtype=float) - offset
            foc["count"] += 1
            if foc["count"] >= foc["n"]:
                self._finish_foc()
        if self._fifo_store_mode:
            select, tag = self._frame_format()
            self._fifo.push(rate_bytes[select] + tag, self._fifo_store_mode)
        if self._fifo_int_on:
            self._update_fifo_int(t_ns)

    # ------------------------------------------------------------------ engines

    def _update_engine_flags(self) -> None:
        r = self._regs
        self._any_axes = r[ANY_EN] & 7
        self._high_axes = (r[0x22] & 1) | (r[0x24] & 1) << 1 | (r[0x26] & 1) << 2
        self._fifo_int_on = bool(r[INT_EN_0] & 0x40)
        mode = r[FIFO_CONFIG_1] >> 6
        if mode == 3:
            mode = choice.FIFO_RESERVED_MODE_AS
        self._fifo_mode = mode
        self._fifo_store_mode = mode if mode in (fifo_mod.FIFO, fifo_mod.STREAM) else 0
        self._per_sample = bool(self._any_axes or self._high_axes or self._foc is not None)

    def _frame_format(self) -> tuple[slice, bytes]:
        select = self._regs[FIFO_CONFIG_1] & 3
        tag = b""
        if self._regs[FIFO_CONFIG_0] & 0x80:
            int1, int2 = self._pins(self.clock.now_ns())
            tag = choice.fifo_tag_bytes(int1, int2)
        return fifo_mod.AXIS_SLICES[select], tag

    def _sync_bypass(self) -> None:
        if self._fifo_mode == fifo_mod.BYPASS and self._have_sample \
                and self._bypass_seq != self._sample_seq:
            axis, tag = self._frame_format()
            self._fifo.replace(self._cur[axis] + tag)
            self._bypass_seq = self._sample_seq

    def _fifo_count(self) -> int:
        self._sync_bypass()
        return self._fifo.count

    def _update_fifo_int(self, now: int) -> None:
        r = self._regs
        if r[INT_EN_0] & 0x40:
            count = self._fifo_count()
            if r[FIFO_WM_EN] & 0x80:
                condition = count >= max(r[FIFO_CONFIG_0] & 0x7F, 1)
            else:
                condition = count >= self._fifo.capacity
        else:
            condition = False
        self._status["fifo"].update(condition, now, latch_hold_ns(r[INT_RST_LATCH]))

    def _finish_foc(self) -> None:
        foc, self._foc = self._foc, None
        if foc is None:
            return
        mean = foc["sum"] / foc["count"]
        new: list[int | None] = [None, None, None]
        for axis in range(3):
            if foc["axes"] >> axis & 1:
                new[axis] = int(np.clip(np.rint(-mean[axis] / self.offset_lsb_dps), -2048, 2047))
        self._set_offsets_lsb(new)
        self._invalidate()
        st = self._status["fast_offset"]
        st.condition, st.seen = True, True  # an event: held until reset_int (spec_choices)
        self._update_engine_flags()

    def _data_int(self, now: int) -> bool:
        if not (self._regs[INT_EN_0] & 0x80 and self._have_sample):
            return False
        if self.hold_data_int:
            return self._data_ready_pending
        return now - self._last_sample_ns < choice.DATA_READY_PULSE_NS

    def _pins(self, now: int) -> tuple[bool, bool]:
        r = self._regs
        st = self._status
        data = self._data_int(now)
        anym = st["any"].pin_active(now)
        high = st["high"].pin_active(now)
        fifo = st["fifo"].pin_active(now)
        fast = st["fast_offset"].pin_active(now)
        auto = st["auto_offset"].pin_active(now)
        m0, m1, m2 = r[INT_MAP_0], r[INT_MAP_1], r[INT_MAP_2]
        int1 = ((m0 & 8 and high) or (m0 & 2 and anym) or (m1 & 1 and data)
                or (m1 & 2 and fast) or (m1 & 4 and fifo) or (m1 & 8 and auto))
        int2 = ((m2 & 8 and high) or (m2 & 2 and anym) or (m1 & 0x80 and data)
                or (m1 & 0x40 and fast) or (m1 & 0x20 and fifo) or (m1 & 0x10 and auto))
        return bool(int1), bool(int2)

    # ------------------------------------------------------------------ register reads

    def _read_burst(self, reg: int, n: int, now: int) -> tuple[bytes, int]:
        """Bytes of one read transaction and the pointer after it (2.4)."""
        out = bytearray(n)
        addr = reg
        for pos in range(n):
            if addr >= FIRST_OUTSIDE_MAP:
                addr = min(addr + n - pos, 0xFF)
                break
            if addr == FIFO_DATA:
                out[pos:] = self._read_fifo(n - pos, now)
                break
            out[pos] = self._read_reg(addr, now)
            addr += 1
        return bytes(out), addr

    def _read_fifo(self, n: int, now: int) -> bytes:
        self._sync_bypass()
        axis, tag = self._frame_format()
        data = self._fifo.read(n, axis.stop - axis.start, bool(tag))
        self._fifo.end_transaction()
        if self._fifo_int_on:
            self._update_fifo_int(now)
        return data

    def _read_reg(self, addr: int, now: int) -> int:
        if 2 <= addr <= 7:
            axis, msb = divmod(addr - 2, 2)
            self._data_ready_pending = False
            if not msb:
                if not self._regs[RATE_HBW] & 0x40:  # shadowing on: latch the MSB (6.2)
                    self._msb_latch[axis] = self._cur[addr - 1]
                    self._latched = True
                return self._cur[addr - 2]
            latched = self._msb_latch[axis]
            if latched is not None:
                self._msb_latch[axis] = None
                if not self._regs[RATE_HBW] & 0x40:
                    return latched
            return self._cur[addr - 2]
        return self._peek_reg(addr, now)

    def _peek_reg(self, addr: int, now: int) -> int:
        r = self._regs
        if addr >= FIRST_OUTSIDE_MAP:
            return 0
        if 2 <= addr <= 7:
            if addr & 1 and not r[RATE_HBW] & 0x40:
                latched = self._msb_latch[(addr - 2) // 2]
                if latched is not None:
                    return latched
            return self._cur[addr - 2]
        if addr == 0x08:
            return self._temp_raw()
        if addr == 0x09:
            lsb = bool(r[INT_RST_LATCH] & 0x10)
            return (self._status["any"].status(now, lsb) << 2
                    | self._status["high"].status(now, lsb) << 1)
        if addr == 0x0A:
            lsb = bool(r[INT_RST_LATCH] & 0x10)
            st = self._status
            return (self._data_int(now) << 7 | st["auto_offset"].status(now, lsb) << 6
                    | st["fast_offset"].status(now, lsb) << 5 | st["fifo"].status(now, lsb) << 4)
        if addr == 0x0B:
            return self._int_status_2
        if addr == 0x0C:
            return self._int_status_3
        if addr == 0x0E:
            count = self._fifo_count()
            return self._fifo.overrun << 7 | count
        if addr == A_FOC:
            return r[A_FOC] | (0x08 if self._foc is not None else 0)
        if addr == TRIM_NVM_CTRL:
            ready = now >= self._nvm_busy_until
            return self._nvm_remain << 4 | ready << 2 | (r[TRIM_NVM_CTRL] & 1)
        if addr == BIST:
            rate_ok = self.power_mode in _SAMPLING_MODES and now >= self._data_start_ns
            rdy = fail = 0
            if self._bist_start is not None and now - self._bist_start >= choice.BIST_TIME_NS:
                rdy, fail = 1, int(self.inject_bist_failure)
            return rate_ok << 4 | fail << 2 | rdy << 1
        if addr == FIFO_DATA:
            self._sync_bypass()
            axis, tag = self._frame_format()
            return self._fifo.peek(axis.stop - axis.start, bool(tag))
        return r[addr]

    def _temp_raw(self) -> int:
        if not self._have_sample:
            return 0
        frozen = self._temp_frozen
        if frozen is not None and self._last_sample_ns <= frozen[1]:
            return frozen[0]
        temp = self._temperature
        if callable(temp):
            temp = float(temp(self._last_sample_ns / NS_PER_S))
        raw = round((temp - choice.TEMP_ZERO_C) / choice.TEMP_LSB_K)
        return max(-128, min(127, raw)) & 0xFF

    # ------------------------------------------------------------------ register writes

    def _write_burst(self, reg: int, data: bytes, now: int) -> int:
        if len(data) > 1:
            self._strict(f"multi-byte write of {len(data)} bytes at 0x{reg:02X} (spec 2.1)")
        addr = reg
        for value in data:
            if addr < FIRST_OUTSIDE_MAP:
                self._write_reg(addr, value, now)
            if addr != FIFO_DATA:
                addr = min(addr + 1, 0xFF)
        return addr

    def _write_reg(self, addr: int, value: int, now: int) -> None:
        mode = power_mode(self._regs[LPM1], self._regs[LPM2])
        if mode == DEEP_SUSPEND and addr not in choice.WRITABLE_IN_DEEP_SUSPEND or \
                mode in (SUSPEND, FAST_POWER_UP) and addr not in choice.WRITABLE_IN_SUSPEND:
            self._strict(f"write of 0x{value:02X} to 0x{addr:02X} ignored in {mode} (6.7)")
            return
        r = self._regs
        mask = WRITE_MASKS[addr]
        old = r[addr]
        new = (old & ~mask & 0xFF) | (value & mask)
        r[addr] = new
        if addr == BGW_SOFTRESET:
            if value == 0xB6:
                self._reset_state(now, powered=False)
        elif addr == RANGE:
            if self._range_sensitivity(old) != self._range_sensitivity(new):
                self._invalidate()
        elif addr == BW:
            if (old ^ new) & 7:
                self._change_bandwidth()
        elif addr in (LPM1, LPM2):
            self._power_transition(mode, addr, value, now)
        elif addr == RATE_HBW:
            if (old ^ new) & 0x80:
                self._invalidate()
            if new & 0x40:
                self._msb_latch = [None, None, None]
                self._latched = False
        elif addr == INT_RST_LATCH:
            if value & 0x80:
                self._reset_int()
            if value & 0x40:
                self._set_offsets_lsb((0, 0, 0))
                self._invalidate()
        elif addr == A_FOC:
            if value & 0x08:
                self._start_foc()
        elif addr == TRIM_NVM_CTRL:
            self._nvm_command(value, now)
        elif addr == BIST:
            if value & 0x01:
                self._bist_start = now
        elif OFC1 <= addr <= 0x3B:
            if old != new and addr != 0x3B:
                self._invalidate()
        elif addr == INT_EN_0:
            if new & ~old & 0x80:
                # 6.3: data_int is set only by samples taken while data_en = 1, so a held
                # data_int (hold_data_int) starts from the first sample after enabling
                self._data_ready_pending = False
        elif addr in (FIFO_CONFIG_0, FIFO_CONFIG_1):
            self._fifo.clear(overrun=addr == FIFO_CONFIG_1)
            self._bypass_seq = self._sample_seq
            self._update_engine_flags()
            self._update_fifo_int(now)
        if addr in _ENGINE_REGS:
            self._engine_config_changed(now)

    def _engine_config_changed(self, now: int) -> None:
        had_any, had_high = self._any_axes, self._high_axes
        self._update_engine_flags()
        hold = latch_hold_ns(self._regs[INT_RST_LATCH])
        if not self._any_axes and had_any:
            self._any.reset()
            self._status["any"].update(False, now, hold)
        elif self._any_axes and not had_any:
            self._any.reset()
        if not self._high_axes and had_high:
            self._high.reset()
            self._status["high"].update(False, now, hold)
        elif self._high_axes and not had_high:
            self._high.reset()
        self._update_fifo_int(now)

    def _power_transition(self, old_mode: str, addr: int, value: int, now: int) -> None:
        new_mode = self.power_mode
        if {old_mode, new_mode} in ({SUSPEND, DEEP_SUSPEND}, {FAST_POWER_UP, DEEP_SUSPEND}):
            self._strict(f"direct switch {old_mode} -> {new_mode} (spec 6.7)")
        if old_mode == new_mode:
            return
        if old_mode == DEEP_SUSPEND and choice.LEAVING_DEEP_SUSPEND_RESETS:
            self._reset_state(now, powered=False)
            if addr == LPM1:
                self._regs[LPM1] = value & WRITE_MASKS[LPM1]
            new_mode = self.power_mode
            if new_mode not in _SAMPLING_MODES:
                self._stop_sampling()
            return
        was, now_sampling = old_mode in _SAMPLING_MODES, new_mode in _SAMPLING_MODES
        if was and not now_sampling:
            self._stop_sampling()
        elif now_sampling and not was:
            wake = choice.FAST_POWER_UP_WAKE_NS if old_mode == FAST_POWER_UP else self._startup_ns
            self._start_sampling(now + wake)

    def _reset_int(self) -> None:
        for st in self._status.values():
            st.reset_latch()
        st = self._status["fast_offset"]
        st.condition = st.seen = False
        self._int_status_2 = self._any.status_byte() if self._any.active else 0
        self._int_status_3 = self._high.status_byte() if self._high.active else 0

    def _start_foc(self) -> None:
        r = self._regs
        st = self._status["fast_offset"]
        st.condition = st.seen = False
        self._foc = {"n": 32 << (r[A_FOC] >> 4 & 3), "axes": r[A_FOC] & 7,
                     "unfilt": bool(r[ANY_TH] & 0x80), "sum": np.zeros(3), "count": 0}
        self._update_engine_flags()

    def _nvm_command(self, value: int, now: int) -> None:
        ready = now >= self._nvm_busy_until
        if value & 0x08:
            if ready:
                for i, addr in enumerate(NVM_ADDRESSES):
                    self._regs[addr] = self._nvm[i]
                self._invalidate()
            else:
                self._strict("nvm_load while NVM busy ignored (6.10)")
        if value & 0x02:
            if ready and self._regs[TRIM_NVM_CTRL] & 1 and self._nvm_remain > 0:
                self._nvm[:] = bytes(self._regs[a] for a in NVM_ADDRESSES)
                self._nvm_remain -= 1
                self._nvm_busy_until = now + choice.NVM_PROG_TIME_NS
            else:
                self._strict("nvm_prog_trig ignored: needs nvm_prog_mode, nvm_rdy and cycles")

    def __repr__(self) -> str:
        return (f"BMG160(address=0x{self.address:02X}, t={self.clock.now():.6f} s, "
                f"mode={self.power_mode}, odr={self._odr} Hz)")
