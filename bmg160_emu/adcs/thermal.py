"""Die temperature over a mission: constant, a table, or an orbit's sunlit/eclipse cycle.

Why: in orbit a CubeSat's gyro swings through tens of degrees every orbit, and the bias change
with temperature is usually the largest error a MEMS gyro has (issue 16). A temperature
source is a callable ``t_s -> deg C``: the chip takes it (``BMG160.set_temperature``), reports
it in TEMP and drives its temperature-dependent errors with it.

The orbit model: the environment steps between a sunlit and an eclipse equilibrium
temperature, and the die follows it as a first-order lag with ``time_constant_s`` (the
thermal mass of board and housing). The cycle starts in its periodic steady state, so every
orbit is alike from the first one on:

    sunlit, from A:   T(t) = T_sun + (A - T_sun) exp(-t / tau)            for 0 <= t < P - E
    eclipse, from B:  T(t) = T_ecl + (B - T_ecl) exp(-(t - P + E) / tau)   for P - E <= t < P
    A = [T_ecl (1 - a_e) + T_sun a_e (1 - a_s)] / (1 - a_s a_e),  a_s = e^-(P-E)/tau, a_e = e^-E/tau

with P the orbital period and E the eclipse duration (about 35 min of a 95 min LEO orbit).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from bmg160_emu.limits import finite_number

TemperatureSource = Callable[[float], float]

# The die's plausible range: beyond the BMG160's -40..+85 deg C operating range (data sheet
# 1.1) with margin for survival cases; TEMP itself saturates at -41..86.5 deg C (spec 5.2).
MIN_C, MAX_C = -150.0, 200.0


class ThermalError(ValueError):
    """A temperature description that cannot be used; the message names the key."""


def _temperature(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not MIN_C <= value <= MAX_C:
        raise ThermalError(f"{what} must be a temperature in deg C within {MIN_C:g}..{MAX_C:g}, "
                           f"not {value!r}"[:300])
    return float(value)


def _positive(value: Any, what: str) -> float:
    number = finite_number(value)
    if number is None or not number > 0:
        raise ThermalError(f"{what} must be a positive number of seconds, not {value!r}"[:300])
    return number


@dataclass(frozen=True)
class OrbitThermalCycle:
    """The die temperature over an orbit (see the module docstring); ``phase_s`` shifts the
    cycle (0: the orbit starts as the spacecraft leaves eclipse)."""

    sunlit_c: float = 60.0
    eclipse_c: float = -20.0
    period_s: float = 95 * 60.0
    eclipse_s: float = 35 * 60.0
    time_constant_s: float = 600.0
    phase_s: float = 0.0

    def __post_init__(self) -> None:
        _temperature(self.sunlit_c, "sunlit_c")
        _temperature(self.eclipse_c, "eclipse_c")
        _positive(self.period_s, "period_s")
        _positive(self.eclipse_s, "eclipse_s")
        _positive(self.time_constant_s, "time_constant_s")
        if not self.eclipse_s < self.period_s:
            raise ThermalError("eclipse_s must be shorter than period_s")
        if finite_number(self.phase_s) is None:
            raise ThermalError("phase_s must be finite")

    @property
    def _start_of_sunlit_c(self) -> float:
        tau = self.time_constant_s
        a_s = math.exp(-(self.period_s - self.eclipse_s) / tau)
        a_e = math.exp(-self.eclipse_s / tau)
        return (self.eclipse_c * (1 - a_e) + self.sunlit_c * a_e * (1 - a_s)) / (1 - a_s * a_e)

    def temperature_c(self, t_s: np.ndarray | float) -> np.ndarray:
        t = np.mod(np.asarray(t_s, dtype=float) + self.phase_s, self.period_s)
        sunlit_s = self.period_s - self.eclipse_s
        tau = self.time_constant_s
        a = self._start_of_sunlit_c
        b = self.sunlit_c + (a - self.sunlit_c) * math.exp(-sunlit_s / tau)
        in_sun = t < sunlit_s
        sun = self.sunlit_c + (a - self.sunlit_c) * np.exp(-t / tau)
        ecl = self.eclipse_c + (b - self.eclipse_c) * np.exp(-(t - sunlit_s) / tau)
        return np.where(in_sun, sun, ecl)

    def __call__(self, t_s: float) -> float:
        return float(self.temperature_c(t_s))


@dataclass(frozen=True)
class TableTemperature:
    """A logged or simulated temperature history, linearly interpolated, held at its ends."""

    times_s: tuple[float, ...]
    temperatures_c: tuple[float, ...]

    def __post_init__(self) -> None:
        t = np.asarray(self.times_s, dtype=float)
        y = np.asarray(self.temperatures_c, dtype=float)
        if t.ndim != 1 or t.shape != y.shape or t.size < 1:
            raise ThermalError("a temperature table needs rows of (t_s, deg C)")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ThermalError("temperature table times must be finite and strictly increasing")
        for value in y:
            _temperature(float(value), "a table temperature")

    def temperature_c(self, t_s: np.ndarray | float) -> np.ndarray:
        return np.interp(np.asarray(t_s, dtype=float), self.times_s, self.temperatures_c)

    def __call__(self, t_s: float) -> float:
        return float(self.temperature_c(t_s))


def thermal_from_dict(data: Mapping[str, Any], where: str = "thermal") -> float | TemperatureSource:
    """A scenario's ``[thermal]`` table: ``kind = "constant"`` (``temperature_c``), ``"orbit"``
    (the OrbitThermalCycle fields) or ``"table"`` (``samples = [[t_s, deg C], ...]``)."""
    if not isinstance(data, Mapping):
        raise ThermalError(f"{where} must be a table ([thermal])")
    kind = data.get("kind", "constant")
    keys = {"constant": {"temperature_c"},
            "orbit": {"sunlit_c", "eclipse_c", "period_s", "eclipse_s", "time_constant_s",
                      "phase_s"},
            "table": {"samples"}}
    if kind not in keys:
        raise ThermalError(f"{where}: kind must be one of {sorted(keys)}, not {kind!r}")
    unknown = set(data) - keys[kind] - {"kind"}
    if unknown:
        raise ThermalError(f"{where}: unknown keys for a {kind} temperature: {sorted(unknown)}")
    try:
        if kind == "constant":
            return _temperature(data.get("temperature_c", 23.0), f"{where}: temperature_c")
        if kind == "orbit":
            values = {k: v for k, v in data.items() if k != "kind"}
            for k, v in values.items():
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise ThermalError(f"{k} must be a number, not {v!r}")
            return OrbitThermalCycle(**values)
        rows = data.get("samples")
        try:
            array = np.asarray(rows, dtype=float) if isinstance(rows, list) else np.zeros((0,))
        except OverflowError:  # an integer beyond a double (TOML digits)
            raise ThermalError("samples must be rows of [t_s, deg C]: a number is beyond a "
                               "double's range") from None
        if array.ndim != 2 or array.shape[1] != 2:
            raise ThermalError("samples must be rows of [t_s, deg C]")
        return TableTemperature(tuple(array[:, 0]), tuple(array[:, 1]))
    except (ThermalError, ValueError, TypeError, OverflowError) as exc:
        message = str(exc)
        raise ThermalError(message if message.startswith(where) else f"{where}: {message}") \
            from None
