"""The ADCS side under test: a gyro bias estimator, an attitude propagator and a monitor
that flags a stuck gyro axis. Plain numpy; quaternions are [w, x, y, z], body to reference.
"""

from __future__ import annotations

import math

import numpy as np


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw])


def small_rotation_deg(q_estimate: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Per-axis attitude error (rotation vector of q_true* q_estimate), in degrees."""
    conj = q_true * np.array([1.0, -1.0, -1.0, -1.0])
    error = quat_multiply(conj, q_estimate)
    if error[0] < 0:
        error = -error
    half = math.atan2(float(np.linalg.norm(error[1:])), float(error[0]))
    norm = np.linalg.norm(error[1:])
    return np.degrees(2 * half * error[1:] / norm) if norm > 0 else np.zeros(3)


class BiasEstimator:
    """Gyro bias as the running mean of the output while the spacecraft is at rest."""

    def __init__(self) -> None:
        self.total = np.zeros(3)
        self.count = 0

    def update(self, rates_dps) -> None:
        for rate in rates_dps:
            self.total += rate
            self.count += 1

    @property
    def bias_dps(self) -> np.ndarray:
        return self.total / self.count


def bias_error_bound_dps(N: float, B: float, K: float, tau_s: float, sigmas: float = 3.0) -> float:
    """How far a tau-second mean may stray from the true bias, from the noise terms.

    The white (N) and rate-random-walk (K) parts of the error of a tau-second mean have
    exactly the Allan variance terms N^2/tau and K^2 tau/3; the correlated bias-instability
    part is at most its stationary variance B^2 (IEEE Std 952 terms).
    """
    return sigmas * math.sqrt(N**2 / tau_s + K**2 * tau_s / 3 + B**2)


class AttitudePropagator:
    """Integrates bias-corrected body rates into an attitude quaternion."""

    def __init__(self, dt_s: float, bias_dps=(0.0, 0.0, 0.0), q0=(1.0, 0.0, 0.0, 0.0)) -> None:
        self.dt_s = dt_s
        self.bias_dps = np.asarray(bias_dps, dtype=float)
        self.q = np.asarray(q0, dtype=float)

    def update(self, rates_dps) -> None:
        for rate in rates_dps:
            rotation = np.radians(np.asarray(rate) - self.bias_dps) * self.dt_s
            angle = float(np.linalg.norm(rotation))
            if angle > 0:
                step = np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * rotation / angle])
                self.q = quat_multiply(self.q, step)
        self.q /= np.linalg.norm(self.q)


class StuckAxisMonitor:
    """Flags an axis whose output repeats the same value for ``limit`` samples in a row.

    A live MEMS gyro never does that: its noise moves the output by many LSB per sample.
    """

    def __init__(self, limit: int = 10) -> None:
        self.limit = limit
        self.last = None
        self.repeats = np.zeros(3, dtype=int)
        self.samples = 0
        self.flagged: dict[int, int] = {}  # axis -> sample number when flagged

    def update(self, rates_dps) -> None:
        for rate in rates_dps:
            rate = np.asarray(rate)
            if self.last is not None:
                same = rate == self.last
                self.repeats = np.where(same, self.repeats + 1, 0)
                for axis in np.flatnonzero(self.repeats + 1 >= self.limit):
                    self.flagged.setdefault(int(axis), self.samples)
            self.last = rate
            self.samples += 1
