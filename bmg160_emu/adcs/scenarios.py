"""True body angular rate over time: the motion an ADCS test puts the emulated gyro through.

A scenario is a sum of motion components (rest, constant rotation, orbital rate, slews with
an acceleration limit, torque-free tumbling with optional detumbling, sinusoidal jitter, a
table from the user's own dynamics simulation, or any Python callable). Rates are floats in
deg/s, never counts, so rates far below one LSB (orbital rate, about 0.06 deg/s in LEO) are
represented exactly and only the chip quantizes them.

Scenario files are TOML::

    name = "nadir pointing with reaction-wheel jitter"
    duration_s = 600.0

    [[motion]]
    kind = "orbital"          # 360 deg per orbit about the orbit normal
    altitude_km = 500.0

    [[motion]]
    kind = "jitter"
    amplitude_dps = [0.002, 0.002, 0.0]
    frequency_hz = 4.0

The same file may also hold ``[[gyro]]`` (mounting, address, bus), ``[[fault]]`` and
``[readout]`` tables; they are kept as given here and read by :mod:`bmg160_emu.adcs.rig`
and :mod:`bmg160_emu.adcs.faults`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.durations import MAX_SIMULATED_S, MAX_TEXT
from bmg160_emu.io.errors import FormatError, loads_toml, read_text
from bmg160_emu.io.formats import read_file
from bmg160_emu.limits import RATE_DPS

# WGS-84 / EGM-96 constants for the orbital period of a circular orbit.
EARTH_MU_KM3_S2 = 398600.4418  # km^3/s^2, EGM-96 gravitational parameter
EARTH_RADIUS_KM = 6378.137  # km, WGS-84 equatorial radius

RateFunction = Callable[[Any], Any]  # t (float, or an array when vectorised) -> 3 deg/s


class ScenarioError(FormatError):
    """A scenario file or description that cannot be used, with the reason."""


def orbital_rate_dps(altitude_km: float) -> float:
    """Mean motion of a circular orbit at ``altitude_km``, in deg/s (Kepler's third law)."""
    if not altitude_km > -EARTH_RADIUS_KM * 0.5:
        raise ScenarioError(f"altitude_km must be above the Earth's centre, not {altitude_km}")
    a = EARTH_RADIUS_KM + altitude_km
    return math.degrees(math.sqrt(EARTH_MU_KM3_S2 / a**3))


# --------------------------------------------------------------------------- motions


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


# --------------------------------------------------------------------------- scenario


@dataclass
class Scenario:
    """The true body rate of one test, plus the rig, fault and readout tables of its file.

    Calling the scenario with a time returns the body rate there, so it can be handed to
    ``BMG160.set_true_rate`` as it is.
    """

    duration_s: float
    motions: list[Motion] = field(default_factory=list)
    name: str = "scenario"
    gyros: list[dict[str, Any]] = field(default_factory=list)
    faults: list[dict[str, Any]] = field(default_factory=list)
    readout: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None
    thermal: Any = None  # die temperature of every gyro: deg C or t -> deg C (adcs.thermal)
    devices: list[dict[str, Any]] = field(default_factory=list)  # [[device]]: stand-ins

    def rate_dps(self, t: float | np.ndarray) -> np.ndarray:
        """True body rate in deg/s: shape (3,) for a scalar time, (n, 3) for n times."""
        times = np.asarray(t, dtype=float)
        flat = np.atleast_1d(times).ravel()
        total = np.zeros((flat.size, 3))
        for motion in self.motions:
            total += motion.rate_dps(flat)
        return total[0] if times.ndim == 0 else total

    def __call__(self, t: float) -> np.ndarray:
        return self.rate_dps(t)

    @classmethod
    def from_callable(
        cls, function: RateFunction, duration_s: float, name: str = "callable"
    ) -> Scenario:
        """A scenario whose true rate is ``function(t)`` in deg/s."""
        _check_duration(duration_s)
        return cls(duration_s=duration_s, motions=[CallableMotion(function=function)], name=name)

    @classmethod
    def constant(cls, rate_dps: Sequence[float], duration_s: float) -> Scenario:
        """A constant rotation (``(0, 0, 0)`` is rest)."""
        _check_duration(duration_s)
        rate = _vector(rate_dps, "rate_dps")
        return cls(duration_s=duration_s, motions=[ConstantRotation(rate=rate)], name="constant")


# Longest scenario: the cap on simulated time (30 days, bmg160_emu.durations); beyond, a tumble
# integrates far ahead, and `record --truth` would simulate for days.
MAX_DURATION_S = MAX_SIMULATED_S  # bmg160_emu.durations: the one cap on simulated time


def _check_duration(duration_s: Any) -> float:
    if isinstance(duration_s, bool) or not isinstance(duration_s, (int, float)) \
            or not 0 < duration_s <= MAX_DURATION_S:
        raise ScenarioError(f"duration_s must be a positive number of seconds up to "
                            f"{MAX_TEXT}, not {duration_s!r}")
    return float(duration_s)


def _finite(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ScenarioError(f"{what} must be a finite number of seconds, not {value!r}")
    return float(value)


# Largest magnitude of any vector or slew value (deg/s, deg, deg/s2): 500 x the +-2000 deg/s range.
MAX_COMPONENT = 1e6


def _vector(value: Any, what: str) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        array = np.zeros(0)
    if array.shape != (3,) or not np.all(np.isfinite(array)) \
            or np.any(np.abs(array) > MAX_COMPONENT):
        raise ScenarioError(f"{what} must be 3 finite numbers (x, y, z) within "
                            f"+-{MAX_COMPONENT:g}, not {value!r}"[:300])
    return array


def _unit(value: Any, what: str) -> np.ndarray:
    vector = _vector(value, what)
    norm = float(np.linalg.norm(vector))
    if norm == 0:
        raise ScenarioError(f"{what} must not be the zero vector")
    return vector / norm


def _positive(entry: dict[str, Any], key: str, where: str, default: float | None = None,
              maximum: float = math.inf) -> float:
    value = entry.get(key, default)
    if value is None:
        raise ScenarioError(f"{where}: missing {key}")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 \
            or not math.isfinite(value):
        raise ScenarioError(f"{where}: {key} must be a positive finite number, not {value!r}")
    if value > maximum:  # jitter: 10 kHz, five times the chip's highest ODR
        raise ScenarioError(f"{where}: {key} must be at most {maximum:g}, not {value!r}")
    return float(value)


def _inertia(value: Any, where: str) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        array = np.zeros(0)
    if array.shape == (3,):
        array = np.diag(array)
    if array.shape != (3, 3) or not np.all(np.isfinite(array)) or not np.allclose(array, array.T):
        raise ScenarioError(f"{where}: inertia_kg_m2 must be 3 principal moments or a 3x3 matrix "
                            "(finite, symmetric)")
    moments = np.sort(np.linalg.eigvalsh(array))
    if np.any(moments <= 0):
        raise ScenarioError(f"{where}: inertia_kg_m2 must be positive definite")
    if moments[0] + moments[1] < moments[2] * (1 - 1e-9):
        # no rigid body has it (the principal moments of any mass distribution obey the
        # triangle inequality); such a body also makes Euler's equations needlessly stiff
        raise ScenarioError(f"{where}: inertia_kg_m2 {moments.tolist()} breaks the triangle "
                            "inequality I1 + I2 >= I3 of principal moments")
    return array


def _load_table(entry: dict[str, Any], where: str, base: Path | None) -> np.ndarray:
    if "samples" in entry:
        try:
            data = np.asarray(entry["samples"], dtype=float)
        except (TypeError, ValueError):
            raise ScenarioError(
                f"{where}: a rate table needs rows of 4 numbers: t_s, x, y, z") from None
    elif "file" in entry:
        path = Path(entry["file"])
        if not path.is_absolute() and base is not None:
            path = base / path
        if not path.exists():
            raise ScenarioError(f"{where}: rate table file not found: {path}")
        try:  # the registry's rate table formats (io/rates.py): .csv, .npy
            data = read_file("rate table", path)
        except FormatError as exc:
            raise ScenarioError(f"{where}: {exc}") from None
    else:
        raise ScenarioError(f"{where}: a table needs 'samples' or 'file'")
    if data.ndim != 2 or data.shape[1] != 4:
        raise ScenarioError(f"{where}: a rate table needs rows of 4 numbers: t_s, x, y, z")
    return data


_MOTION_KEYS = {
    "rest": set(),
    "constant": {"rate_dps"},
    "orbital": {"altitude_km", "period_s", "axis"},
    "slew": {"axis", "angle_deg", "max_rate_dps", "max_accel_dps2"},
    "jitter": {"amplitude_dps", "frequency_hz", "phase_deg"},
    "tumble": {"initial_rate_dps", "inertia_kg_m2", "damping_time_s"},
    "table": {"samples", "file", "units", "interpolation"},
}


def motion_from_dict(
    entry: dict[str, Any], duration_s: float, where: str = "motion", base: Path | None = None
) -> Motion:
    """Build one motion component from its TOML table."""
    kind = entry.get("kind")
    if not isinstance(kind, str) or kind not in _MOTION_KEYS:
        raise ScenarioError(f"{where}: kind must be one of {sorted(_MOTION_KEYS)}, not {kind!r}")
    unknown = set(entry) - _MOTION_KEYS[kind] - {"kind", "start_s", "end_s"}
    if unknown:
        raise ScenarioError(f"{where}: unknown keys for a {kind} motion: {sorted(unknown)}")
    start = _finite(entry.get("start_s", 0.0), f"{where}: start_s")
    end = entry.get("end_s")
    if end is not None:
        end = _finite(end, f"{where}: end_s")
        if not end > start:
            raise ScenarioError(f"{where}: end_s must be after start_s")
    window: dict[str, Any] = {"start_s": start, "end_s": end}

    if kind == "rest":
        return Rest(**window)
    if kind == "constant":
        return ConstantRotation(rate=_vector(entry.get("rate_dps"), f"{where}: rate_dps"), **window)
    if kind == "orbital":
        if ("altitude_km" in entry) == ("period_s" in entry):
            raise ScenarioError(f"{where}: an orbital motion needs altitude_km or period_s")
        if "period_s" in entry:
            rate = 360.0 / _positive(entry, "period_s", where)
        else:
            rate = orbital_rate_dps(float(entry["altitude_km"]))
        # Nadir pointing in LVLH: the body turns about the negative orbit normal (-y).
        axis = _unit(entry.get("axis", [0.0, -1.0, 0.0]), f"{where}: axis")
        return ConstantRotation(rate=rate * axis, **window)
    if kind == "slew":
        angle = entry.get("angle_deg")
        if isinstance(angle, bool) or not isinstance(angle, (int, float)) \
                or not abs(angle) <= MAX_COMPONENT:  # 1e308 overflowed its rate profile
            raise ScenarioError(f"{where}: a slew needs angle_deg, a number within +-1e6")
        if end is not None:
            raise ScenarioError(f"{where}: a slew ends by itself when its rate profile does; "
                                "give start_s only (end_s is for the other motions)")
        return Slew(
            axis=_unit(entry.get("axis"), f"{where}: axis"),
            angle_deg=float(angle),
            max_rate_dps=_positive(entry, "max_rate_dps", where, maximum=MAX_COMPONENT),
            max_accel_dps2=_positive(entry, "max_accel_dps2", where, maximum=MAX_COMPONENT),
            start_s=start,
        )
    if kind == "jitter":
        return Jitter(
            amplitude_dps=_vector(entry.get("amplitude_dps"), f"{where}: amplitude_dps"),
            frequency_hz=_positive(entry, "frequency_hz", where, maximum=1e4),
            phase_deg=_vector(entry.get("phase_deg", [0.0, 0.0, 0.0]), f"{where}: phase_deg"),
            **window,
        )
    if kind == "tumble":
        damping = entry.get("damping_time_s")
        if damping is not None:
            damping = _positive(entry, "damping_time_s", where)
        return Tumble(
            initial_rate_dps=_vector(entry.get("initial_rate_dps"), f"{where}: initial_rate_dps"),
            inertia_kg_m2=_inertia(entry.get("inertia_kg_m2", [1.0, 1.0, 1.0]), where),
            damping_time_s=damping,
            horizon_s=min(duration_s, 600.0) + 10.0,  # then extended as far as asked
            **window,
        )
    # table
    data = _load_table(entry, where, base)
    units = entry.get("units", "deg/s")
    if units not in ("deg/s", "rad/s"):
        raise ScenarioError(f"{where}: units must be 'deg/s' or 'rad/s', not {units!r}")
    scale = 1.0 if units == "deg/s" else 180.0 / math.pi
    beyond = np.abs(data[:, 1:]) > RATE_DPS.high / scale  # before scaling: no overflow
    if beyond.any():
        row = int(np.argmax(beyond.any(axis=1)))
        raise ScenarioError(f"{where}: table row {row + 1}: a rate beyond {RATE_DPS.describe()}")
    rates = data[:, 1:] * scale
    return Table(
        times_s=data[:, 0],
        rates_dps=rates,
        interpolation=entry.get("interpolation", "linear"),
        **window,
    )


_TOP_KEYS = {"name", "description", "duration_s", "motion", "gyro", "fault", "readout",
             "thermal", "device"}


def scenario_from_dict(data: dict[str, Any], base: Path | None = None) -> Scenario:
    """Build a scenario from the parsed content of a scenario file."""
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise ScenarioError(f"unknown top-level keys: {sorted(unknown)} (expected {sorted(_TOP_KEYS)})")
    duration = _check_duration(data.get("duration_s"))
    entries = data.get("motion", [{"kind": "rest"}])
    if not isinstance(entries, list):
        raise ScenarioError("motion must be an array of tables ([[motion]])")
    for key in ("motion", "gyro", "fault", "device"):
        listed = data.get(key, [])
        if not isinstance(listed, list) or not all(isinstance(e, dict) for e in listed):
            raise ScenarioError(f"{key} must be an array of tables ([[{key}]])")
    if not isinstance(data.get("readout", {}), dict):
        raise ScenarioError("readout must be a table ([readout])")
    motions = [
        motion_from_dict(entry, duration, where=f"motion {i + 1}", base=base)
        for i, entry in enumerate(entries)
    ]
    thermal = None
    if "thermal" in data:
        from bmg160_emu.adcs.thermal import ThermalError, thermal_from_dict

        try:
            thermal = thermal_from_dict(data["thermal"])
        except ThermalError as exc:
            raise ScenarioError(str(exc)) from None
    return Scenario(
        duration_s=duration,
        motions=motions,
        name=str(data.get("name", "scenario")),
        gyros=list(data.get("gyro", [])),
        faults=list(data.get("fault", [])),
        readout=dict(data.get("readout", {})),
        thermal=thermal,
        devices=list(data.get("device", [])),
    )


def load_scenario(path: str | Path) -> Scenario:
    """Read a TOML scenario file; relative table files are found next to it."""
    path = Path(path)
    try:
        text = read_text(path, ScenarioError)
    except OSError as exc:
        raise ScenarioError(f"cannot read scenario {path}: {exc.strerror}") from None
    data = loads_toml(text, ScenarioError, str(path))
    try:
        scenario = scenario_from_dict(data, base=path.parent)
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: {exc}") from None
    scenario.source = path
    if scenario.name == "scenario":
        scenario.name = path.stem
    return scenario
