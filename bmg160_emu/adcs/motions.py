"""The motion components a scenario sums: rest, a constant rotation (the orbital rate among
them), a slew with an acceleration limit, sinusoidal jitter, a torque-free tumble with
optional detumbling, a table from the user's own dynamics simulation, and any Python
callable. Each gives the true body rate in deg/s over its active window."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bmg160_emu.adcs.scenario_values import ScenarioError

# WGS-84 / EGM-96 constants for the orbital period of a circular orbit.
EARTH_MU_KM3_S2 = 398600.4418  # km^3/s^2, EGM-96 gravitational parameter
EARTH_RADIUS_KM = 6378.137  # km, WGS-84 equatorial radius

RateFunction = Callable[[Any], Any]  # t (float, or an array when vectorised) -> 3 deg/s


def orbital_rate_dps(altitude_km: float) -> float:
    """Mean motion of a circular orbit at ``altitude_km``, in deg/s (Kepler's third law)."""
    if not altitude_km > -EARTH_RADIUS_KM * 0.5:
        raise ScenarioError(f"altitude_km must be above the Earth's centre, not {altitude_km}")
    a = EARTH_RADIUS_KM + altitude_km
    return math.degrees(math.sqrt(EARTH_MU_KM3_S2 / a**3))


@dataclass
class Motion:
    """One motion component, active on ``[start_s, end_s)`` (``end_s`` None = forever)."""

    start_s: float = 0.0
    end_s: float | None = None

    def _active(self, t: np.ndarray) -> np.ndarray:
        mask = t >= self.start_s
        if self.end_s is not None:
            mask &= t < self.end_s
        return mask

    def rate_dps(self, t: np.ndarray) -> np.ndarray:
        """Body rate (n, 3) in deg/s at times ``t`` (n,), zero outside the active window."""
        out = np.zeros((t.size, 3))
        mask = self._active(t)
        if mask.any():
            out[mask] = self._rate(t[mask])
        return out

    def _rate(self, t: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError


@dataclass
class Rest(Motion):
    """No rotation (the gyro sees only its own bias and noise)."""

    def _rate(self, t: np.ndarray) -> np.ndarray:
        return np.zeros((t.size, 3))


@dataclass
class ConstantRotation(Motion):
    """A constant body rate in deg/s, exactly as given (no quantization)."""

    rate: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def _rate(self, t: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.rate, (t.size, 3)).copy()


@dataclass
class Slew(Motion):
    """A rest-to-rest eigenaxis slew with a rate and an acceleration limit.

    The rate profile is trapezoidal (accelerate at ``max_accel_dps2``, coast at
    ``max_rate_dps``, decelerate), or triangular when the angle is too small to reach the
    rate limit. The slew ends by itself after :attr:`duration_s`.
    """

    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    angle_deg: float = 0.0
    max_rate_dps: float = 1.0
    max_accel_dps2: float = 1.0

    def __post_init__(self) -> None:
        angle = abs(self.angle_deg)
        # Peak rate: reached rate limit, or the triangular profile's sqrt(angle * accel).
        self.peak_dps = min(self.max_rate_dps, math.sqrt(angle * self.max_accel_dps2))
        self.ramp_s = self.peak_dps / self.max_accel_dps2
        ramp_angle = self.peak_dps * self.ramp_s  # both ramps together
        self.coast_s = (angle - ramp_angle) / self.peak_dps if self.peak_dps > 0 else 0.0
        self.duration_s = 2 * self.ramp_s + self.coast_s
        if self.end_s is None:
            self.end_s = self.start_s + self.duration_s
        self._sign = math.copysign(1.0, self.angle_deg)

    def _rate(self, t: np.ndarray) -> np.ndarray:
        tau = t - self.start_s
        up = self.max_accel_dps2 * tau
        down = self.max_accel_dps2 * (self.duration_s - tau)
        speed = np.clip(np.minimum(np.minimum(up, down), self.peak_dps), 0.0, None)
        return self._sign * speed[:, None] * self.axis[None, :]


@dataclass
class Jitter(Motion):
    """Sinusoidal rate ``amplitude * sin(2 pi f (t - start) + phase)`` per axis."""

    amplitude_dps: np.ndarray = field(default_factory=lambda: np.zeros(3))
    frequency_hz: float = 1.0
    phase_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def _rate(self, t: np.ndarray) -> np.ndarray:
        arg = 2 * math.pi * self.frequency_hz * (t - self.start_s)
        return self.amplitude_dps * np.sin(arg[:, None] + np.radians(self.phase_deg)[None, :])


@dataclass
class Tumble(Motion):
    """Torque-free rigid-body tumbling (Euler's equations) after deployment.

    With ``damping_time_s`` a rate-damping torque ``-I w / damping_time_s`` (an ideal
    detumbling controller) makes the angular momentum decay exponentially while the body
    keeps nutating. Solved with dense output, in pieces as far ahead as asked.
    """

    initial_rate_dps: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia_kg_m2: np.ndarray = field(default_factory=lambda: np.eye(3))
    damping_time_s: float | None = None
    horizon_s: float = 60.0

    def __post_init__(self) -> None:
        self._inverse = np.linalg.inv(self.inertia_kg_m2)
        self._damping = 0.0 if self.damping_time_s is None else 1.0 / self.damping_time_s
        # dense-output pieces (t_lo, t_hi, solution), extended on demand: the chip asks for
        # rates ahead of time, beyond the scenario's duration
        self._pieces: list[tuple[float, float, Any]] = []
        self._extend(self.start_s + max(self.horizon_s, 1.0))

    def _euler(self, _t: float, w: np.ndarray) -> np.ndarray:
        return self._inverse @ (-np.cross(w, self.inertia_kg_m2 @ w)) - self._damping * w

    def _extend(self, until_s: float) -> None:
        from scipy.integrate import solve_ivp

        if self._pieces:
            _, t0, last = self._pieces[-1]
            w0 = last(t0)
        else:
            t0, w0 = self.start_s, np.radians(self.initial_rate_dps)
        stop = max(until_s, t0 + max(self.horizon_s, 1.0))
        solution = solve_ivp(self._euler, (t0, stop), w0, method="DOP853", dense_output=True,
                             rtol=1e-11, atol=1e-14)
        if not solution.success:  # pragma: no cover - smooth ODE
            raise ScenarioError(f"tumble: Euler's equations failed: {solution.message}")
        self._pieces.append((t0, stop, solution.sol))

    def _rate(self, t: np.ndarray) -> np.ndarray:
        if t.size and t.max() > self._pieces[-1][1]:
            self._extend(float(t.max()))
        out = np.empty((t.size, 3))
        for lo, hi, solution in self._pieces:
            mask = (t >= lo) & (t <= hi)
            if mask.any():
                out[mask] = solution(t[mask]).T
        return np.degrees(out)


@dataclass
class Table(Motion):
    """Body rates sampled by the user's own dynamics simulation, interpolated in time."""

    times_s: np.ndarray = field(default_factory=lambda: np.zeros(1))
    rates_dps: np.ndarray = field(default_factory=lambda: np.zeros((1, 3)))
    interpolation: str = "linear"

    def __post_init__(self) -> None:
        if self.interpolation not in ("linear", "previous"):
            raise ScenarioError(
                f"table interpolation must be 'linear' or 'previous', not {self.interpolation!r}"
            )
        if self.times_s.ndim != 1 or self.rates_dps.shape != (self.times_s.size, 3):
            raise ScenarioError("a rate table needs rows of 4 numbers: t_s, x, y, z")
        if self.times_s.size < 1 or np.any(np.diff(self.times_s) <= 0):
            raise ScenarioError("rate table times must be strictly increasing")

    def _rate(self, t: np.ndarray) -> np.ndarray:
        if self.interpolation == "previous":
            index = np.clip(np.searchsorted(self.times_s, t, side="right") - 1, 0, None)
            return self.rates_dps[index]
        return np.stack(
            [np.interp(t, self.times_s, self.rates_dps[:, k]) for k in range(3)], axis=1
        )


@dataclass
class CallableMotion(Motion):
    """Any Python callable ``f(t) -> (x, y, z)`` in deg/s (vectorised or not)."""

    function: RateFunction | None = None

    def _rate(self, t: np.ndarray) -> np.ndarray:
        assert self.function is not None
        values = self._vectorised(t)
        if values is not None:
            return values
        rows = [np.asarray(self.function(float(x)), dtype=float) for x in t]
        for row in rows:
            if row.shape != (3,):
                raise ScenarioError(
                    f"a rate callable must return 3 numbers (deg/s), got shape {row.shape}"
                )
        return np.array(rows).reshape(t.size, 3)

    def _vectorised(self, t: np.ndarray) -> np.ndarray | None:
        """One call with all times, when the callable accepts arrays; else None."""
        function = self.function
        assert function is not None
        try:
            values = np.asarray(function(t), dtype=np.float64)
        except Exception:  # noqa: BLE001 - a scalar-only callable: called per time instead
            return None
        if t.size == 3 and values.shape == (3, 3):
            # (n, 3) or (3, n)? A call with two times tells which layout the callable uses.
            try:
                probe = np.asarray(function(t[:2]), dtype=np.float64)
            except Exception:  # noqa: BLE001 - no clear layout: called per time instead
                return None
            if probe.shape == (2, 3):
                return values
            return values.T if probe.shape == (3, 2) else None
        if values.shape == (t.size, 3):
            return values
        if values.shape == (3, t.size):
            return values.T
        return None
