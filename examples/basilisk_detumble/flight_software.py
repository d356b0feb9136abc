"""The example's flight software: a Basilisk module that knows the gyro only through smbus2.

It runs at 20 Hz (``PERIOD_S``), as CubeSat ADCS loops commonly do, and takes every one of
the gyro's 200 Hz samples from the BMG160's FIFO (stream mode, X, Y, Z frames; spec 4.26,
6.5): each step it reads FIFO_STATUS for the frame count, then the frames in one combined
I2C transfer (plain ``smbus2``; under ``patch_smbus`` they come from the emulated chip, with
its filter, noise and faults). That is how drivers keep the bus and the CPU quiet (PX4 and
ArduPilot read the BMI055/BMI088 gyro's FIFO the same way). Then it checks the samples,
estimates rate and attitude and commands the three reaction wheels:

- detumble: ``L = -Kd I w + w x (I w + h)`` (rate damping with the gyroscopic term
  cancelled, so each axis decays as ``exp(-Kd t)``);
- inertial pointing (once the rate is low and a star tracker fix is in): MRP feedback
  ``L = I (-K sigma_BR - P w) + w x (I w + h)`` with ``sigma_BR`` from the estimated
  attitude (target ``sigma_RN = 0``, as Basilisk's inertial3D).

Estimation: rate = counts / LSB - ground-calibrated bias - bias corrections, averaged over
the step's frames; attitude = quaternion turned by that mean rate times the step (with 10
samples a step, the sum of the samples' rates times the sample period: the integral of the
measured rate, so every sample's angle random walk is in it), reset to each star-tracker
fix, whose innovation also updates the bias estimate.

Fault detection (each onset and recovery goes to ``events``, timed by the sample that
showed it: frame j of n read at t was sampled at about ``t - (n - 1 - j) / ODR``):
- NACK (``OSError`` from smbus2): the rate comes from the momentum model below until reads
  succeed again; the FIFO keeps the samples of the outage (100 frames, 0.5 s at 200 Hz);
- stuck axis: an axis whose counts do not change for ``STUCK_SAMPLES`` samples (with the
  chip's noise, about 12 LSB rms after its filter, a repeat has probability ~0.03 per
  sample, so 8 in a row ~1e-12) is replaced by the model until it moves;
- bias step: the residual between the gyro and a momentum model (``I dw = -dh - w x (I w
  + h) dt``, with ``h`` from the wheel tachometers, so wheel friction is included) is
  averaged over 0.1 s; above ``step_threshold_dps`` for 0.25 s the step is declared, its size
  is the residual's mean over that time, and it is subtracted from then on.

The step works on plain Python floats (3-vectors as lists): numpy's per-call overhead on
3-element arrays would cost more than the arithmetic.
"""

from __future__ import annotations

import math
import struct
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from Basilisk.architecture import messaging, sysModel
from smbus2 import SMBus, i2c_msg

# BMG160 register map (spec 3, 4.7, 4.26, 4.27)
FIFO_STATUS, RANGE, BW, FIFO_CONFIG_1, FIFO_DATA = 0x0E, 0x0F, 0x10, 0x3E, 0x3F
RANGE_250_DPS, BW_200_HZ = 0x03, 0x04  # RANGE code 3 = +-250 deg/s; BW code 4 = ODR 200 Hz
FIFO_STREAM_XYZ = 0x80  # fifo_mode 2 (stream: the newest 100 frames), data select 0 (X, Y, Z)
FRAME_COUNT_MASK = 0x7F  # FIFO_STATUS bits 6:0, fifo_frame_counter
FRAME_BYTES = 6  # X, Y, Z int16 LSB first, no tag
LSB_PER_DPS = 32768 / 250  # the model's "binary" sensitivity at +-250 deg/s
SAMPLE_S = 0.005  # the gyro's output period at 200 Hz
PERIOD_S = 0.05  # the flight software's step: 10 samples a step
_FRAME = struct.Struct("<3h")

STUCK_SAMPLES = 8
STEP_WINDOW_S = 0.1  # the residual mean (2 steps, 20 samples)
STEP_CONFIRM_S = 0.25  # above threshold this long before a bias step is declared (5 steps)
STEP_THRESHOLD_DPS = 0.15  # 0.1 s mean of the residual; its noise is ~0.02 deg/s rms with
# the paper's gyro (FlightConfig.step_threshold_dps: scaled with the flown gyro's N)
BASELINE_TAU_S = 1.0  # the residual's level before a step: a slow mean
OBSERVER_TAU_S = 2.0  # the model rate follows the gyro with a 2 s time constant
ST_MAX_RATE_DPS = 1.0  # star tracker fixes are used only below this rate
STARTUP_S = 0.1  # data sheet: 30 ms start-up after power-on; the software waits 0.1 s
CHECKS_FROM_S = 1.0  # the model locks on (fast gain) for 0.9 s before residuals are judged
LOCK_TAU_S = 0.1
POINT_AFTER_S = 2.0  # with the smoothed rate below point_rate_dps


@dataclass
class FlightConfig:
    inertia: np.ndarray  # kg m^2, body frame
    wheel_axes: np.ndarray  # (3, n) spin axes in the body frame
    wheel_js: float  # kg m^2, wheel spin inertia
    wheel_u_max: float  # N m
    bias_cal_dps: np.ndarray  # ground calibration (identification mean)
    kd: float = 0.05  # 1/s, detumble rate gain
    k: float = 0.04  # 1/s^2, attitude gain (MRP): wn = sqrt(K/4) = 0.1 rad/s
    p: float = 0.18  # 1/s, rate gain: zeta = P / (2 wn) = 0.9
    # switch to pointing below this (smoothed estimate, for 2 s, with a star-tracker fix):
    # 0.03 deg/s under the 0.1 deg/s goal covers the estimate's residual bias (~0.02 deg/s)
    point_rate_dps: float = 0.07
    bias_gain: float = 0.3  # fraction of the star-tracker drift taken into the bias
    # the residual's 0.1 s mean beyond this is a bias step: a noisier gyro needs a higher
    # threshold for the same false-alarm rate (scenario.step_threshold_dps)
    step_threshold_dps: float = 0.15
    dt_s: float = PERIOD_S  # the flight software's step (its Basilisk task's period)


@dataclass
class Event:
    time_s: float
    kind: str
    detail: str


@dataclass
class FlightLog:
    time_s: list = field(default_factory=list)
    rate_est_dps: list = field(default_factory=list)  # the gyro's rate, per step
    rate_model_dps: list = field(default_factory=list)  # the smoothed (model) rate
    sigma_est: list = field(default_factory=list)
    mode: list = field(default_factory=list)
    torque_cmd: list = field(default_factory=list)


class FlightSoftware(sysModel.SysModel):
    """Reads the gyro's FIFO over smbus2, estimates rate and attitude, commands the wheels."""

    def __init__(self, config: FlightConfig, bus: int = 1, address: int = 0x68,
                 log_every: int = 2) -> None:
        super().__init__()
        self.ModelTag = "flightSoftware"
        self.cfg = config
        self.bus_number, self.address = bus, address
        self.rwSpeedInMsg = messaging.RWSpeedMsgReader()
        self.starTrackerInMsg = messaging.STAttMsgReader()
        self.rwMotorTorqueOutMsg = messaging.ArrayMotorTorqueMsg()
        self.torque_payload = messaging.ArrayMotorTorqueMsgPayload()
        self.inertia = _rows(config.inertia)
        self.inv_inertia = _rows(np.linalg.inv(config.inertia))
        self.allocation = _rows(-np.linalg.pinv(config.wheel_axes))  # body L -> wheel torques
        self.momentum = _rows(np.asarray(config.wheel_axes) * config.wheel_js)  # speeds -> h
        self.n_wheels = int(np.asarray(config.wheel_axes).shape[1])
        self.events: list[Event] = []
        self.log = FlightLog()
        self.log_every = log_every
        self.st_updates: list[tuple[float, np.ndarray]] = []  # time, pre-update quaternion
        dt = config.dt_s
        self.step_window = max(1, round(STEP_WINDOW_S / dt))
        self.step_confirm = max(1, round(STEP_CONFIRM_S / dt))
        self.observer_gain, self.lock_gain = dt / OBSERVER_TAU_S, min(1.0, dt / LOCK_TAU_S)
        self.point_after = max(1, round(POINT_AFTER_S / dt))

    # ------------------------------------------------------------------ setup

    def Reset(self, CurrentSimNanos: int) -> None:
        # the wheel speeds through one live view of their message, taken once its link is
        # made (each call of a reader makes a new reader and view: 5-10 us)
        self.wheel_speeds = self.rwSpeedInMsg()
        self.smbus = SMBus(self.bus_number)
        self.smbus.write_byte_data(self.address, RANGE, RANGE_250_DPS)
        self.smbus.write_byte_data(self.address, BW, BW_200_HZ)
        self.smbus.write_byte_data(self.address, FIFO_CONFIG_1, FIFO_STREAM_XYZ)  # empties it
        self.fifo_select = i2c_msg.write(self.address, [FIFO_DATA])
        self.mode = "detumble"
        self.omega = [0.0, 0.0, 0.0]  # rad/s: the gyro's rate (model on bad axes)
        self.omega_model: list[float] | None = None  # rad/s, momentum-model rate
        self.bias_dps = [float(b) for b in self.cfg.bias_cal_dps]
        self.q: list[float] | None = None  # attitude (body -> inertial), from the first fix
        self.last_counts: tuple[int, int, int] | None = None
        self.same = [0, 0, 0]
        self.stuck = [False, False, False]
        self.suspect = [0, 0, 0]
        # the residual's level before a step (a slow mean, 1 s): what the model leaves over
        # (calibration error it has not yet absorbed), taken off a step's size
        self.baseline = [0.0, 0.0, 0.0]
        self._clear_residuals()
        self.nack = False
        self.h_prev: list[float] | None = None
        self.last_fix_ns = -1
        self.last_fix_s: float | None = None
        self.steps = 0
        self.calm = 0

    def _clear_residuals(self) -> None:
        self.residuals: deque[list[float]] = deque(maxlen=self.step_window)
        self.residual_sum = [0.0, 0.0, 0.0]
        self.suspect_sum = [0.0, 0.0, 0.0]  # residual sums over each axis's suspect run

    def _event(self, t: float, kind: str, detail: str) -> None:
        self.events.append(Event(t, kind, detail))

    # ------------------------------------------------------------------ the step

    def UpdateState(self, CurrentSimNanos: int) -> None:
        t = CurrentSimNanos * 1e-9
        speeds = self.wheel_speeds.wheelSpeeds
        (m0, m1, m2) = self.momentum
        h = [_dot(m0, speeds), _dot(m1, speeds), _dot(m2, speeds)]  # N m s, body
        if t < STARTUP_S:
            self._read_frames(t)  # (the samples of the start-up: not used)
            self._command([0.0, 0.0, 0.0], CurrentSimNanos)
            self.h_prev = h
            return
        before = self.omega_model
        self._propagate_model(h)
        measured = self._read_gyro(t)
        model = self.omega_model
        if model is None or before is None:
            if measured is None:
                return
            model = self.omega_model = list(measured)
            before = model
        # the samples' mean is the rate of mid-step: the model is compared there (the mean
        # of its value at the step's two ends), not at t, 25 ms later (at 1 deg/s^2 that
        # lag alone would be a 0.025 deg/s residual)
        mid = [(a + b) * 0.5 for a, b in zip(before, model)]
        if measured is not None and t >= CHECKS_FROM_S:
            self._check(t, measured, mid)
        omega = list(model)
        if measured is not None:
            gain = self.observer_gain if t >= CHECKS_FROM_S else self.lock_gain
            for axis in range(3):
                if self.stuck[axis]:
                    continue
                omega[axis] = measured[axis]
                if not self.suspect[axis]:  # the model follows, not while a step is judged
                    model[axis] += gain * (measured[axis] - mid[axis])
        self.omega = omega
        self._attitude(t)
        torque = self._control(h, t)
        self._command(torque, CurrentSimNanos)
        self.h_prev = h
        if self.steps % self.log_every == 0:
            self.log.time_s.append(t)
            self.log.rate_est_dps.append([math.degrees(w) for w in omega])
            self.log.rate_model_dps.append([math.degrees(w) for w in model])
            self.log.sigma_est.append(_mrp(self.q) if self.q is not None else [math.nan] * 3)
            self.log.mode.append(self.mode)
            self.log.torque_cmd.append(torque)
        self.steps += 1

    def _read_frames(self, t: float) -> bytes | None:
        """The FIFO's frames, oldest first: FIFO_STATUS for the count, then one combined
        transfer (register pointer to FIFO_DATA, repeated start, 6 bytes a frame; the pointer
        stays at FIFO_DATA, spec 4.27). None when a read fails."""
        try:
            n = self.smbus.read_byte_data(self.address, FIFO_STATUS) & FRAME_COUNT_MASK
            if not n:
                return b""
            frames = i2c_msg.read(self.address, n * FRAME_BYTES)
            self.smbus.i2c_rdwr(self.fifo_select, frames)
        except OSError as exc:
            if not self.nack:
                self._event(t, "nack", f"gyro read failed: {exc}; rate from the momentum model")
                self.nack = True
            return None
        if self.nack:
            self._event(t, "nack cleared", "gyro reads again")
            self.nack = False
        return bytes(frames)

    def _read_gyro(self, t: float) -> list[float] | None:
        """The mean rate (rad/s) of the samples since the last step (10 at 200 Hz and 20 Hz),
        or None when none came (a failed read, or an empty FIFO)."""
        data = self._read_frames(t)
        if not data:
            return None
        n = len(data) // FRAME_BYTES
        sums = [0.0, 0.0, 0.0]
        same, stuck, last = self.same, self.stuck, self.last_counts
        for j, counts in enumerate(_FRAME.iter_unpack(data)):  # little-endian int16 x, y, z
            for axis in range(3):
                c = counts[axis]
                sums[axis] += c
                if last is None:
                    continue
                same[axis] = same[axis] + 1 if c == last[axis] else 0
                if not stuck[axis] and same[axis] >= STUCK_SAMPLES - 1:
                    stuck[axis] = True
                    self._event(t - (n - 1 - j) * SAMPLE_S, "stuck axis",
                                f"{'xyz'[axis]}: {STUCK_SAMPLES} identical counts ({c}); "
                                "axis from the momentum model")
                elif stuck[axis] and same[axis] == 0:
                    stuck[axis] = False
                    self._event(t - (n - 1 - j) * SAMPLE_S, "stuck axis cleared",
                                f"{'xyz'[axis]} moves again")
            last = counts
        self.last_counts = last
        bias = self.bias_dps
        return [math.radians(s / n / LSB_PER_DPS - b) for s, b in zip(sums, bias)]

    def _propagate_model(self, h: list[float]) -> None:
        w = self.omega_model
        if w is None or self.h_prev is None:
            return
        dt = self.cfg.dt_s
        gyro = _cross(w, _add(_mv(self.inertia, w), h))
        hp = self.h_prev
        change = _mv(self.inv_inertia, [-(h[0] - hp[0]) - gyro[0] * dt,
                                        -(h[1] - hp[1]) - gyro[1] * dt,
                                        -(h[2] - hp[2]) - gyro[2] * dt])
        self.omega_model = _add(w, change)

    def _check(self, t: float, measured: list[float], model: list[float]) -> None:
        """Bias-step detection on the gyro-minus-model residual."""
        residual = [math.degrees(m - w) for m, w in zip(measured, model)]
        sums = self.residual_sum
        window = self.step_window
        if len(self.residuals) == window:
            # the residual leaving the window goes into the level: a step's first residuals
            # are judged (suspect) before they could leave, so the level stays the one before
            oldest = self.residuals[0]
            follow = self.cfg.dt_s / BASELINE_TAU_S
            for axis in range(3):
                sums[axis] -= oldest[axis]
                if not self.suspect[axis]:
                    self.baseline[axis] += follow * (oldest[axis] - self.baseline[axis])
        self.residuals.append(residual)
        for axis in range(3):
            sums[axis] += residual[axis]
        if len(self.residuals) < window:
            return
        limit = self.cfg.step_threshold_dps * window
        if all(abs(x) < limit for x in sums) and not any(self.suspect):
            return
        for axis in range(3):
            if self.stuck[axis] or abs(sums[axis]) < limit:
                self.suspect[axis] = 0
                self.suspect_sum[axis] = 0.0
                continue
            self.suspect[axis] += 1
            self.suspect_sum[axis] += residual[axis]
            if self.suspect[axis] >= self.step_confirm:
                step = self.suspect_sum[axis] / self.step_confirm - self.baseline[axis]
                self.bias_dps[axis] += step
                self.suspect[axis] = 0
                self._clear_residuals()
                onset = t - (self.step_confirm + window) * self.cfg.dt_s
                self._event(t, "bias step", f"{'xyz'[axis]}: {step:+.3f} deg/s (onset near "
                            f"{onset:.2f} s); subtracted from now on")
                return

    def _attitude(self, t: float) -> None:
        dt = self.cfg.dt_s
        if self.q is not None:  # the step's mean rate over the step: the samples' integral
            self.q = _quat_mul(self.q, _quat_exp([w * dt for w in self.omega]))
        msg = self.starTrackerInMsg
        if not msg.isWritten() or msg.timeWritten() == self.last_fix_ns:
            return
        self.last_fix_ns = msg.timeWritten()
        if math.degrees(math.sqrt(sum(w * w for w in self.omega))) > ST_MAX_RATE_DPS:
            return
        fix = _quat_from_mrp(list(msg().MRP_BdyInrtl))
        if self.q is not None and self.last_fix_s is not None:
            self.st_updates.append((t, np.array(self.q)))
            delta = _quat_mul(_quat_conj(self.q), fix)  # propagated -> measured, body frame
            sign = math.copysign(2.0, delta[0])
            span = t - self.last_fix_s
            for axis in range(3):
                change_dps = -self.cfg.bias_gain * math.degrees(sign * delta[axis + 1]) / span
                self.bias_dps[axis] += change_dps
                # the corrected rate moves by -change: the model (a smoother of it) moves along
                if self.omega_model is not None:
                    self.omega_model[axis] -= math.radians(change_dps)
            self._clear_residuals()
        self.q = fix
        self.last_fix_s = t

    def _control(self, h: list[float], t: float) -> list[float]:
        cfg = self.cfg
        w = self.omega_model  # the smoothed rate: control and mode decisions
        assert w is not None
        rate_dps = math.degrees(math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]))
        if self.mode == "detumble":
            self.calm = self.calm + 1 if rate_dps < cfg.point_rate_dps else 0
            if self.q is not None and self.calm >= self.point_after:
                self.mode = "point"
                self._event(t, "mode", f"rate below {cfg.point_rate_dps} deg/s for "
                            f"{self.point_after * cfg.dt_s:g} s: inertial pointing")
        iw = _mv(self.inertia, w)
        gyroscopic = _cross(w, _add(iw, h))
        if self.mode == "detumble":
            kd = cfg.kd
            return [-kd * iw[0] + gyroscopic[0], -kd * iw[1] + gyroscopic[1],
                    -kd * iw[2] + gyroscopic[2]]
        assert self.q is not None
        sigma = _mrp(self.q)
        inner = [-cfg.k * s - cfg.p * x for s, x in zip(sigma, w)]
        return _add(_mv(self.inertia, inner), gyroscopic)

    def _command(self, torque: list[float], now_ns: int) -> None:
        # body torque from the wheels is -G u: least-squares wheel torques for -L
        u_max = self.cfg.wheel_u_max
        u = [min(max(x, -u_max), u_max) for x in _mv(self.allocation, torque)]
        self.torque_payload.motorTorque = u
        self.rwMotorTorqueOutMsg.write(self.torque_payload, now_ns, self.moduleID)


# ---------------------------------------------------------------------- small vector algebra

def _rows(matrix) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(x) for x in row) for row in np.asarray(matrix, dtype=float))


def _dot(row, v) -> float:
    """A row of a matrix times a vector: the row's length, v may be longer (Basilisk's
    wheelSpeeds holds 36 entries for the first n wheels)."""
    total = 0.0
    for a, b in zip(row, v):
        total += a * b
    return total


def _mv(m, v) -> list[float]:
    return [_dot(row, v) for row in m]


def _add(a, b) -> list[float]:
    return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]


def _cross(a, b) -> list[float]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


# quaternions [w, x, y, z], Hamilton, body -> inertial (as bmg160_emu.adcs.attitude)

def _quat_mul(p, q) -> list[float]:
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return [pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw]


def _quat_conj(q) -> list[float]:
    return [q[0], -q[1], -q[2], -q[3]]


def _quat_exp(rotation) -> list[float]:
    angle = math.sqrt(sum(r * r for r in rotation))
    if angle < 1e-12:
        return [1.0, *(0.5 * r for r in rotation)]
    scale = math.sin(angle / 2) / angle
    return [math.cos(angle / 2), *(r * scale for r in rotation)]


def _quat_from_mrp(sigma) -> list[float]:
    s2 = sum(x * x for x in sigma)
    return [(1.0 - s2) / (1.0 + s2), *(2.0 * x / (1.0 + s2) for x in sigma)]


def _mrp(q) -> list[float]:
    w, x, y, z = q
    if w < 0:  # the short rotation (|sigma| <= 1)
        w, x, y, z = -w, -x, -y, -z
    return [x / (1.0 + w), y / (1.0 + w), z / (1.0 + w)]
