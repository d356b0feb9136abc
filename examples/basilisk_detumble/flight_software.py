"""The example's flight software: a Basilisk module that knows the gyro only through smbus2.

Every 5 ms it reads the six rate bytes of the BMG160 over I2C (plain ``smbus2``; under
``patch_smbus`` they come from the emulated chip, with its filter, noise and faults), turns
them into a body rate, checks them, and commands the three reaction wheels:

- detumble: ``L = -Kd I w + w x (I w + h)`` (rate damping with the gyroscopic term
  cancelled, so each axis decays as ``exp(-Kd t)``);
- inertial pointing (once the rate is low and a star tracker fix is in): MRP feedback
  ``L = I (-K sigma_BR - P w) + w x (I w + h)`` with ``sigma_BR`` from the estimated
  attitude (target ``sigma_RN = 0``, as Basilisk's inertial3D).

Estimation: rate = counts / LSB - ground-calibrated bias - bias corrections; attitude =
quaternion propagated with that rate, reset to each star-tracker fix, whose innovation also
updates the bias estimate.

Fault detection (each onset and recovery goes to ``events``):
- NACK (``OSError`` from smbus2): the rate comes from the momentum model below until reads
  succeed again;
- stuck axis: an axis whose counts do not change for ``STUCK_SAMPLES`` reads (with the
  chip's noise, about 12 LSB rms after its filter, a repeat has probability ~0.03 per
  read, so 8 in a row ~1e-12) is replaced by the model until it moves;
- bias step: the residual between the gyro and a momentum model (``I dw = -dh - w x (I w
  + h) dt``, with ``h`` from the wheel tachometers, so wheel friction is included) is
  averaged over 0.1 s; above ``STEP_THRESHOLD_DPS`` for 0.25 s the step is declared, its size
  is the residual's mean over that time, and it is subtracted from then on.

The hot path works on plain Python floats (3-vectors as lists): numpy's per-call overhead
on 3-element arrays would cost more than the arithmetic, at 200 steps a second.
"""

from __future__ import annotations

import math
import struct
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from Basilisk.architecture import messaging, sysModel
from smbus2 import SMBus

RANGE, BW, RATE_X_LSB = 0x0F, 0x10, 0x02  # BMG160 register map (spec 3)
RANGE_250_DPS, BW_200_HZ = 0x03, 0x04  # RANGE code 3 = +-250 deg/s; BW code 4 = ODR 200 Hz
LSB_PER_DPS = 32768 / 250  # the model's "binary" sensitivity at +-250 deg/s
_STRUCT_XYZ = struct.Struct("<3h")

STUCK_SAMPLES = 8
STEP_WINDOW = 20  # samples (0.1 s at 200 Hz) in the residual mean
STEP_CONFIRM = 50  # samples (0.25 s) above threshold before a bias step is declared
STEP_THRESHOLD_DPS = 0.15  # 0.1 s mean of the residual; its noise is ~0.02 deg/s rms
OBSERVER_GAIN = 1.0 / 400  # the model rate follows the gyro with a 2 s time constant
ST_MAX_RATE_DPS = 1.0  # star tracker fixes are used only below this rate
STARTUP_S = 0.1  # data sheet: 30 ms start-up after power-on; the software waits 0.1 s
CHECKS_FROM_S = 1.0  # the model locks on (fast gain) for 0.9 s before residuals are judged
LOCK_GAIN = 0.05
POINT_AFTER = 400  # steps (2 s) with the smoothed rate below point_rate_dps


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
    dt_s: float = 0.005


@dataclass
class Event:
    time_s: float
    kind: str
    detail: str


@dataclass
class FlightLog:
    time_s: list = field(default_factory=list)
    rate_est_dps: list = field(default_factory=list)  # the gyro's rate, per sample
    rate_model_dps: list = field(default_factory=list)  # the smoothed (model) rate
    sigma_est: list = field(default_factory=list)
    mode: list = field(default_factory=list)
    torque_cmd: list = field(default_factory=list)


class FlightSoftware(sysModel.SysModel):
    """Reads the gyro over smbus2, estimates rate and attitude, commands the wheels."""

    def __init__(self, config: FlightConfig, bus: int = 1, address: int = 0x68,
                 log_every: int = 20) -> None:
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

    # ------------------------------------------------------------------ setup

    def Reset(self, CurrentSimNanos: int) -> None:
        self.smbus = SMBus(self.bus_number)
        self.smbus.write_byte_data(self.address, RANGE, RANGE_250_DPS)
        self.smbus.write_byte_data(self.address, BW, BW_200_HZ)
        self.mode = "detumble"
        self.omega = [0.0, 0.0, 0.0]  # rad/s: the gyro's rate (model on bad axes)
        self.omega_model: list[float] | None = None  # rad/s, momentum-model rate
        self.bias_dps = [float(b) for b in self.cfg.bias_cal_dps]
        self.q: list[float] | None = None  # attitude (body -> inertial), from the first fix
        self.last_counts: tuple[int, int, int] | None = None
        self.same = [0, 0, 0]
        self.stuck = [False, False, False]
        self.suspect = [0, 0, 0]
        self._clear_residuals()
        self.nack = False
        self.h_prev: list[float] | None = None
        self.last_fix_ns = -1
        self.last_fix_s: float | None = None
        self.steps = 0
        self.calm = 0

    def _clear_residuals(self) -> None:
        self.residuals: deque[list[float]] = deque(maxlen=STEP_WINDOW)
        self.residual_sum = [0.0, 0.0, 0.0]
        self.suspect_sum = [0.0, 0.0, 0.0]  # residual sums over each axis's suspect run

    def _event(self, t: float, kind: str, detail: str) -> None:
        self.events.append(Event(t, kind, detail))

    # ------------------------------------------------------------------ the step

    def UpdateState(self, CurrentSimNanos: int) -> None:
        t = CurrentSimNanos * 1e-9
        speeds = self.rwSpeedInMsg().wheelSpeeds[: self.n_wheels]
        h = [sum(r * w for r, w in zip(row, speeds)) for row in self.momentum]  # N m s, body
        if t < STARTUP_S:
            self._command([0.0, 0.0, 0.0], CurrentSimNanos)
            self.h_prev = h
            return
        self._propagate_model(h)
        measured = self._read_gyro(t)
        model = self.omega_model
        if model is None:
            if measured is None:
                return
            model = self.omega_model = list(measured)
        if measured is not None and t >= CHECKS_FROM_S:
            self._check(t, measured)
        omega = list(model)
        if measured is not None:
            gain = OBSERVER_GAIN if t >= CHECKS_FROM_S else LOCK_GAIN
            for axis in range(3):
                if self.stuck[axis]:
                    continue
                omega[axis] = measured[axis]
                if not self.suspect[axis]:  # the model follows, not while a step is judged
                    model[axis] += gain * (measured[axis] - model[axis])
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

    def _read_gyro(self, t: float) -> list[float] | None:
        try:
            raw = self.smbus.read_i2c_block_data(self.address, RATE_X_LSB, 6)
        except OSError as exc:
            if not self.nack:
                self._event(t, "nack", f"gyro read failed: {exc}; rate from the momentum model")
                self.nack = True
            return None
        if self.nack:
            self._event(t, "nack cleared", "gyro reads again")
            self.nack = False
        counts = _STRUCT_XYZ.unpack(bytes(raw))  # little-endian int16 x, y, z (spec 3)
        last = self.last_counts
        self.last_counts = counts
        if last is not None:
            for axis in range(3):
                self.same[axis] = self.same[axis] + 1 if counts[axis] == last[axis] else 0
                if not self.stuck[axis] and self.same[axis] >= STUCK_SAMPLES - 1:
                    self.stuck[axis] = True
                    self._event(t, "stuck axis", f"{'xyz'[axis]}: {STUCK_SAMPLES} identical "
                                f"counts ({counts[axis]}); axis from the momentum model")
                elif self.stuck[axis] and self.same[axis] == 0:
                    self.stuck[axis] = False
                    self._event(t, "stuck axis cleared", f"{'xyz'[axis]} moves again")
        bias = self.bias_dps
        return [math.radians(c / LSB_PER_DPS - b) for c, b in zip(counts, bias)]

    def _propagate_model(self, h: list[float]) -> None:
        w = self.omega_model
        if w is None or self.h_prev is None:
            return
        dt = self.cfg.dt_s
        gyro = _cross(w, [a + b for a, b in zip(_mv(self.inertia, w), h)])
        change = _mv(self.inv_inertia, [-(a - b) - g * dt for a, b, g in zip(h, self.h_prev, gyro)])
        self.omega_model = [a + b for a, b in zip(w, change)]

    def _check(self, t: float, measured: list[float]) -> None:
        """Bias-step detection on the gyro-minus-model residual."""
        model = self.omega_model
        assert model is not None
        residual = [math.degrees(m - w) for m, w in zip(measured, model)]
        sums = self.residual_sum
        if len(self.residuals) == STEP_WINDOW:
            oldest = self.residuals[0]
            for axis in range(3):
                sums[axis] -= oldest[axis]
        self.residuals.append(residual)
        for axis in range(3):
            sums[axis] += residual[axis]
        if len(self.residuals) < STEP_WINDOW:
            return
        limit = STEP_THRESHOLD_DPS * STEP_WINDOW
        if all(abs(x) < limit for x in sums) and not any(self.suspect):
            return
        for axis in range(3):
            if self.stuck[axis] or abs(sums[axis]) < limit:
                self.suspect[axis] = 0
                self.suspect_sum[axis] = 0.0
                continue
            self.suspect[axis] += 1
            self.suspect_sum[axis] += residual[axis]
            if self.suspect[axis] >= STEP_CONFIRM:
                step = self.suspect_sum[axis] / STEP_CONFIRM
                self.bias_dps[axis] += step
                self.suspect[axis] = 0
                self._clear_residuals()
                onset = t - (STEP_CONFIRM + STEP_WINDOW) * self.cfg.dt_s
                self._event(t, "bias step", f"{'xyz'[axis]}: {step:+.3f} deg/s (onset near "
                            f"{onset:.2f} s); subtracted from now on")
                return

    def _attitude(self, t: float) -> None:
        dt = self.cfg.dt_s
        if self.q is not None:
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
        rate_dps = math.degrees(math.sqrt(sum(x * x for x in w)))
        if self.mode == "detumble":
            self.calm = self.calm + 1 if rate_dps < cfg.point_rate_dps else 0
            if self.q is not None and self.calm >= POINT_AFTER:
                self.mode = "point"
                self._event(t, "mode", f"rate below {cfg.point_rate_dps} deg/s for "
                            f"{POINT_AFTER * cfg.dt_s:g} s: inertial pointing")
        iw = _mv(self.inertia, w)
        gyroscopic = _cross(w, [a + b for a, b in zip(iw, h)])
        if self.mode == "detumble":
            return [-cfg.kd * a + g for a, g in zip(iw, gyroscopic)]
        assert self.q is not None
        sigma = _mrp(self.q)
        inner = [-cfg.k * s - cfg.p * x for s, x in zip(sigma, w)]
        return [a + g for a, g in zip(_mv(self.inertia, inner), gyroscopic)]

    def _command(self, torque: list[float], now_ns: int) -> None:
        # body torque from the wheels is -G u: least-squares wheel torques for -L
        u_max = self.cfg.wheel_u_max
        u = [min(max(x, -u_max), u_max) for x in _mv(self.allocation, torque)]
        self.torque_payload.motorTorque = u
        self.rwMotorTorqueOutMsg.write(self.torque_payload, now_ns, self.moduleID)


# ---------------------------------------------------------------------- small vector algebra

def _rows(matrix) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(x) for x in row) for row in np.asarray(matrix, dtype=float))


def _mv(m, v) -> list[float]:
    return [sum(a * b for a, b in zip(row, v)) for row in m]


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
