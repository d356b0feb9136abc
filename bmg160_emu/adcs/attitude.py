"""The true attitude: body rate integrated into a quaternion at every output sample.

Convention (stated once, used everywhere in :mod:`bmg160_emu.adcs`): quaternions are
scalar-first ``[w, x, y, z]`` Hamilton quaternions; ``q`` maps body-frame vectors into the
reference frame (``v_ref = q v_body q*``); the body rate ``w`` (deg/s, body frame) drives
``dq/dt = 1/2 q (0, w)``.

Integration uses the fourth-order Magnus (commutator) step with two Gauss points: the
rotation vector over a step of length ``h`` is ``h/2 (w1 + w2) + sqrt(3)/12 h^2 (w1 x w2)``
(the cross term is the classic coning correction), exact for a constant rate and fourth
order for a varying one, and the quaternion keeps unit norm by construction.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])

_GAUSS_OFFSET = math.sqrt(3.0) / 6.0  # Gauss-Legendre nodes at 1/2 -+ sqrt(3)/6
_MAGNUS_CROSS = math.sqrt(3.0) / 12.0

RateOfTime = Callable[[np.ndarray], np.ndarray]  # (n,) seconds -> (n, 3) deg/s


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p q`` (broadcasts over leading axes)."""
    pw, px, py, pz = np.moveaxis(np.asarray(p, dtype=float), -1, 0)
    qw, qx, qy, qz = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """The inverse rotation of a unit quaternion."""
    return np.asarray(q, dtype=float) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_from_rotation_vector(rotation_rad: np.ndarray) -> np.ndarray:
    """``exp(rotation / 2)``: the rotation by ``|rotation|`` radians about its direction."""
    rotation = np.asarray(rotation_rad, dtype=float)
    angle = np.linalg.norm(rotation, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(x/2)/x written so that it stays exact near zero
    scale = np.where(angle > 1e-8, np.sin(half) / np.where(angle > 0, angle, 1.0), 0.5 - angle**2 / 48)
    return np.concatenate([np.cos(half), rotation * scale], axis=-1)


def quat_from_axis_angle(axis: np.ndarray, angle_deg: float) -> np.ndarray:
    """Rotation by ``angle_deg`` about ``axis`` (normalised here)."""
    axis = np.asarray(axis, dtype=float)
    return quat_from_rotation_vector(axis / np.linalg.norm(axis) * math.radians(angle_deg))


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``q v q*``: a body vector expressed in the reference frame."""
    v = np.asarray(v, dtype=float)
    pure = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
    return quat_multiply(quat_multiply(q, pure), quat_conjugate(q))[..., 1:]


def angle_between_deg(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angle in degrees of the rotation that takes attitude ``q`` to attitude ``p``."""
    error = quat_multiply(quat_conjugate(q), p)
    vector = np.linalg.norm(error[..., 1:], axis=-1)
    return np.degrees(2.0 * np.arctan2(vector, np.abs(error[..., 0])))


def magnus_increments(rate_of_time: RateOfTime, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """Quaternion increments (n, 4) over the steps ``[t0[i], t1[i]]`` (vectorised)."""
    t0 = np.asarray(t0, dtype=float)
    h = np.asarray(t1, dtype=float) - t0
    w1 = np.radians(rate_of_time(t0 + (0.5 - _GAUSS_OFFSET) * h))
    w2 = np.radians(rate_of_time(t0 + (0.5 + _GAUSS_OFFSET) * h))
    rotation = 0.5 * h[:, None] * (w1 + w2) + _MAGNUS_CROSS * (h**2)[:, None] * np.cross(w1, w2)
    return quat_from_rotation_vector(rotation)


def chain_rotations(q0: np.ndarray, increments: np.ndarray) -> np.ndarray:
    """Cumulative right products ``q0 d1 d2 ...`` (sequential, on plain floats for speed)."""
    w, x, y, z = (float(c) for c in q0)
    out = np.empty((increments.shape[0], 4))
    for i, (dw, dx, dy, dz) in enumerate(increments.tolist()):
        w, x, y, z = (
            w * dw - x * dx - y * dy - z * dz,
            w * dx + x * dw + y * dz - z * dy,
            w * dy - x * dz + y * dw + z * dx,
            w * dz + x * dy - y * dx + z * dw,
        )
        out[i] = (w, x, y, z)
    # re-normalise once: rounding drift only, the increments are unit quaternions
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def integrate_attitude(
    rate_of_time: RateOfTime,
    times_s: np.ndarray,
    q0: np.ndarray = IDENTITY,
    t0: float | None = None,
    max_step_s: float = 1e-3,
) -> np.ndarray:
    """True attitude quaternions (n, 4) at ``times_s`` (increasing), from ``q0`` at ``t0``.

    ``rate_of_time`` maps an array of times to body rates (n, 3) in deg/s (a
    :class:`~bmg160_emu.adcs.scenarios.Scenario`'s ``rate_dps`` does). Each interval is
    split into equal sub-steps no longer than ``max_step_s``.
    """
    times = np.asarray(times_s, dtype=float)
    if times.ndim != 1:
        raise ValueError("times_s must be a 1-D array of times")
    start = float(times[0]) if t0 is None else float(t0)
    edges = np.concatenate([[start], times])
    if np.any(np.diff(edges) < 0):
        raise ValueError("times_s must be increasing and not before t0")
    widths = np.diff(edges)
    substeps = np.maximum(1, np.ceil(widths / max_step_s - 1e-9).astype(int))
    # sub-step boundaries, all intervals at once
    owner = np.repeat(np.arange(times.size), substeps)
    first = np.concatenate([[0], np.cumsum(substeps)[:-1]])
    k = np.arange(owner.size) - first[owner]
    h = widths[owner] / substeps[owner]
    sub_t0 = edges[owner] + k * h
    increments = magnus_increments(rate_of_time, sub_t0, sub_t0 + h)
    path = chain_rotations(np.asarray(q0, dtype=float), increments)
    last = np.cumsum(substeps) - 1
    return path[last]


class AttitudeIntegrator:
    """The true attitude followed step by step (for truth recorded as samples arrive)."""

    def __init__(
        self,
        rate_of_time: RateOfTime,
        q0: np.ndarray = IDENTITY,
        t0: float = 0.0,
        max_step_s: float = 1e-3,
    ) -> None:
        self.rate_of_time = rate_of_time
        self.q = np.asarray(q0, dtype=float).copy()
        self.t = float(t0)
        self.max_step_s = max_step_s

    def advance_to(self, t: float) -> np.ndarray:
        """Integrate up to time ``t`` and return the attitude there."""
        if t < self.t:
            raise ValueError(f"cannot integrate backwards from {self.t} s to {t} s")
        if t > self.t:
            self.q = integrate_attitude(
                self.rate_of_time, np.array([t]), self.q, self.t, self.max_step_s
            )[0]
            self.t = float(t)
        return self.q.copy()
