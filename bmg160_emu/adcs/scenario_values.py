"""The values of a scenario file, checked: each bad one is a :class:`ScenarioError` naming its
key, before anything runs (durations within the cap on simulated time, finite numbers,
3-vectors within +-1e6, unit axes, positive keys, a rigid body's inertia)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bmg160_emu.durations import MAX_SIMULATED_S, MAX_TEXT
from bmg160_emu.io.errors import FormatError
from bmg160_emu.limits import finite_number


class ScenarioError(FormatError):
    """A scenario file or description that cannot be used, with the reason."""


# Longest scenario: the cap on simulated time (30 days, bmg160_emu.durations); beyond, a tumble
# integrates far ahead, and `record --truth` would simulate for days.
MAX_DURATION_S = MAX_SIMULATED_S  # bmg160_emu.durations: the one cap on simulated time


def check_duration(duration_s: Any) -> float:
    """``duration_s``: positive seconds, at most the cap on simulated time."""
    if isinstance(duration_s, bool) or not isinstance(duration_s, (int, float)) \
            or not 0 < duration_s <= MAX_DURATION_S:
        raise ScenarioError(f"duration_s must be a positive number of seconds up to "
                            f"{MAX_TEXT}, not {duration_s!r}")
    return float(duration_s)


def finite_seconds(value: Any, what: str) -> float:
    """A time in seconds (``start_s``, ``end_s``) within +-the cap on simulated time: a
    motion may have started before the scenario (a tumble is integrated from its start),
    but not further back than any run may simulate (a tumble from -1e308 s overflowed the
    integrator: tools/fuzz.py, scenario seed 7951583)."""
    number = finite_number(value)
    if number is None or abs(number) > MAX_DURATION_S:
        raise ScenarioError(f"{what} must be a finite number of seconds within +-{MAX_TEXT}, "
                            f"not {value!r}"[:300])
    return number


# Largest magnitude of any vector or slew value (deg/s, deg, deg/s2): 500 x the +-2000 deg/s range.
MAX_COMPONENT = 1e6


def vector3(value: Any, what: str) -> np.ndarray:
    """Three finite numbers (x, y, z) within +-MAX_COMPONENT."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        array = np.zeros(0)
    if array.shape != (3,) or not np.all(np.isfinite(array)) \
            or np.any(np.abs(array) > MAX_COMPONENT):
        raise ScenarioError(f"{what} must be 3 finite numbers (x, y, z) within "
                            f"+-{MAX_COMPONENT:g}, not {value!r}"[:300])
    return array


def unit_vector(value: Any, what: str) -> np.ndarray:
    """An axis: a non-zero 3-vector, normalised."""
    vector = vector3(value, what)
    norm = float(np.linalg.norm(vector))
    if norm == 0:
        raise ScenarioError(f"{what} must not be the zero vector")
    return vector / norm


def positive_key(entry: dict[str, Any], key: str, where: str, default: float | None = None,
              maximum: float = math.inf) -> float:
    """``entry[key]`` (or ``default``): a positive finite number, at most ``maximum``."""
    value = entry.get(key, default)
    if value is None:
        raise ScenarioError(f"{where}: missing {key}")
    number = finite_number(value)
    if number is None or not number > 0:
        raise ScenarioError(
            f"{where}: {key} must be a positive finite number, not {value!r}"[:300])
    if number > maximum:  # jitter: 10 kHz, five times the chip's highest ODR
        raise ScenarioError(f"{where}: {key} must be at most {maximum:g}, not {value!r}"[:300])
    return number


def inertia_matrix(value: Any, where: str) -> np.ndarray:
    """3 principal moments or a symmetric 3x3 matrix of a rigid body, in kg m^2."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):  # (an integer beyond a double's range)
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
