"""The unit's error budget in the chip's data path, and the inputs that drive it.

Why a module of its own: the deterministic errors of a unit (bmg160_emu.noise.sensor_errors)
depend on the die temperature (the same one TEMP reports), on the acceleration the chip feels
(g-sensitivity) and on the power cycle (turn-on bias); the chip's data path applies them to
the sensor-frame true rate before its low-pass filter (issue 16). ``ErrorBudget`` is that
stage; the chip's public inputs and views of it are ``BMG160.set_acceleration``,
``sensor_errors`` and ``turn_on_bias_dps``.

Which errors a chip has, in order of precedence: ``errors=`` given to the chip, else unit
``unit=`` of the part drawn from the data sheet's tolerances and the chip's seed
(bmg160_emu.device.unit_population), else the noise profile's ``errors`` table, else none.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from bmg160_emu.clock import NS_PER_S
from bmg160_emu.noise.sensor_errors import NO_ERRORS, SensorErrors, TurnOnBias

FULL_SCALE_LSB = 32768.0  # the int16 full scale: FS in deg/s is this over the sensitivity


def errors_for(errors: Any, unit: int | None, seed: int | None, profile: Any,
               source: Any = None) -> SensorErrors:
    """The chip's errors from its options (the module docstring's precedence); ``source``,
    the profile as the chip was given it (a name or a path), names it in an error (issue 35:
    a file with name = "paper" was reported as "profile paper")."""
    if errors is not None:
        if isinstance(errors, SensorErrors):
            return errors
        if isinstance(errors, Mapping):
            return SensorErrors.from_dict(errors)
        raise TypeError(f"errors must be a SensorErrors or a table of its fields, not "
                        f"{type(errors).__name__}")
    if unit is not None:
        from bmg160_emu.device.unit_population import draw_unit

        if seed is None:
            raise ValueError("unit= draws a unit of a lot: give the chip a seed (the lot)")
        return draw_unit(int(seed), unit)
    where = f"profile {getattr(profile, 'name', profile)} [errors]"
    if isinstance(source, (str, os.PathLike)):
        where = f"{os.fspath(source)} [errors]"
    if profile is not None and not hasattr(profile, "axes"):
        from bmg160_emu.noise import load_profile

        where = f"{profile} [errors]"  # the file (or name) as given: the message names it
        profile = load_profile(profile)
    table = getattr(profile, "errors", None)
    if table:
        return table if isinstance(table, SensorErrors) else SensorErrors.from_dict(table, where)
    return NO_ERRORS


def _check_acceleration(value: Any) -> Any:
    if callable(value):
        return value
    array = np.asarray(value, dtype=float)
    if array.shape != (3,) or not np.all(np.isfinite(array)) or np.any(np.abs(array) > 1e4):
        raise ValueError(f"acceleration must be 3 finite numbers in g (within +-1e4) or a "
                         f"callable of t, not {value!r}")
    return array


class ErrorBudget:
    """The error stage of one chip: ``apply`` to a block of sensor-frame rates."""

    def __init__(self, errors: SensorErrors, seed: int | None, address: int,
                 thermometer: Any, times_ns: Callable[[int, int], np.ndarray]) -> None:
        self.errors = errors
        turn_on_seed = None if seed is None else int(np.random.SeedSequence(
            [int(seed), int(address)]).generate_state(1, np.uint64)[0])
        self._turn_on = TurnOnBias(errors.turn_on_bias_sigma_dps, turn_on_seed)
        self.turn_on_bias_dps = np.zeros(3)
        self.acceleration_g: Any = np.zeros(3)
        self._thermometer = thermometer
        self._times_ns = times_ns

    @classmethod
    def of(cls, errors: Any, unit: int | None, acceleration_g: Any, generator_or_profile: Any,
           *, seed: int | None, address: int, thermometer: Any,
           times_ns: Callable[[int, int], np.ndarray], source: Any = None) -> ErrorBudget:
        """The budget of a chip from its constructor's options, its thermometer and the
        times of its samples (``state.ChipState.times_ns``)."""
        profile = getattr(generator_or_profile, "profile", generator_or_profile)
        budget = cls(errors_for(errors, unit, seed, profile, source), seed, address,
                     thermometer, times_ns)
        budget.set_acceleration(acceleration_g)
        return budget

    @property
    def active(self) -> bool:
        return self.errors.active

    @property
    def time_varying(self) -> bool:
        """Whether a constant true rate still gives a varying sensed rate."""
        return self.active and (callable(self._thermometer.temperature_c)
                                or callable(self.acceleration_g))

    def power_cycle(self) -> None:
        """Power-on, soft reset, leaving deep suspend: a fresh turn-on bias from the seed."""
        if any(self.errors.turn_on_bias_sigma_dps):
            self.turn_on_bias_dps = self._turn_on.next()

    def set_acceleration(self, acceleration_g: Any) -> None:
        self.acceleration_g = _check_acceleration(acceleration_g)

    def apply(self, x: np.ndarray, k0: int, sensitivity: float) -> np.ndarray:
        """Samples k0 .. k0 + len(x) - 1 as this unit senses them."""
        n = len(x)
        temp = self._thermometer.temperature_c
        accel = self.acceleration_g
        times_s = None
        if callable(temp) or callable(accel):
            times_s = self._times_ns(k0, n) / NS_PER_S
        temps = _evaluate(temp, times_s, (n,), "temperature") if callable(temp) else temp
        if callable(accel):
            accel = _evaluate(accel, times_s, (n, 3), "acceleration")
        return self.errors.apply(x, temps, FULL_SCALE_LSB / sensitivity, accel,
                                 self.turn_on_bias_dps)


def _evaluate(function: Callable[[Any], Any], times_s: Any, shape: tuple[int, ...],
              what: str) -> np.ndarray:
    """``function`` at every time: vectorised when it takes an array, else sample by sample."""
    try:
        out = np.asarray(function(times_s), dtype=float)
        if out.shape == shape:
            return out
    except (TypeError, ValueError):
        pass
    out = np.array([np.asarray(function(float(t)), dtype=float) for t in times_s])
    if out.shape != shape or not np.all(np.isfinite(out)):
        raise ValueError(f"the {what} function must return finite values of shape "
                         f"{shape[1:] or 'one number'} per time")
    return out
