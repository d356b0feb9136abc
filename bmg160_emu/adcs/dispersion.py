"""Noise parameters dispersed within an identification's confidence intervals.

A Monte Carlo run should not take the identified N, B, K as exact: the record they came
from was finite, and ``bmg160-emu identify --json`` says how finite through a 95 %
interval per parameter. :class:`NoiseDispersion` draws each run's N, B, K (per axis) from a
two-piece normal with the estimate as its median and the interval ends as its 2.5 % and
97.5 % quantiles: below the estimate a half-normal of ``sigma = (value - low) / 1.96``,
above one of ``sigma = (high - value) / 1.96``, each side with probability 1/2 (so an
asymmetric interval keeps its asymmetry). Draws below zero (an interval reaching 0, as K
often does for records shorter than a few hours) are set to 0. T and the constant bias come
from the base profile; only the named parameters are dispersed.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.noise.profile import load_profile

Z_975 = 1.959963984540054  # standard normal 97.5 % quantile (the identification's 95 % CI)
AXES = ("x", "y", "z")


class DispersionError(ValueError):
    """An identification result that cannot be dispersed, with the file and the place."""


@dataclass(frozen=True)
class Interval:
    """An estimate and its 95 % confidence interval."""

    value: float
    low: float
    high: float

    def draw(self, rng: np.random.Generator) -> float:
        """One value of the two-piece normal (median ``value``, 95 % range low..high)."""
        z = abs(float(rng.standard_normal()))
        side = rng.random() < 0.5
        if side:
            out = self.value - z * (self.value - self.low) / Z_975
        else:
            out = self.value + z * (self.high - self.value) / Z_975
        return max(out, 0.0)


def _interval(entry: Any, where: str) -> Interval:
    try:
        value = float(entry["value"])
        low, high = (float(v) for v in entry["ci95"])
    except (KeyError, TypeError, ValueError):
        raise DispersionError(f"{where}: needs 'value' and 'ci95': [low, high] (numbers)") from None
    if not (math.isfinite(value) and math.isfinite(low) and math.isfinite(high)) \
            or not low <= value <= high:
        raise DispersionError(f"{where}: needs finite low <= value <= high, got {low}, {value}, "
                              f"{high}")
    return Interval(value, low, high)


def identified_axes(result: Mapping[str, Any], origin: str = "identification"
                    ) -> dict[str, Mapping[str, Any]]:
    """The x, y and z tables of ``identify --json`` output, as a noise profile names them.

    ``identify`` keys its axes by the record's column names (``gyro_x``, or ``a`` of
    ``--columns a,b,c``) while a profile (``--profile-out``) names them x, y, z in the
    record's column order (issue 35: the example looked up ``x`` in a ``gyro_x`` result, a
    KeyError, and the dispersion quietly gave every axis the first axis's intervals). Keys
    x, y, z are taken as they are; names that end in x, y and z (``gyro_x``, ``wx``) by that
    letter; any other names in their order. A record of one or two axes lends its first
    axis to the missing ones."""
    axes = result.get("axes") if isinstance(result, Mapping) else None
    if not isinstance(axes, Mapping) or not axes:
        raise DispersionError(f"{origin}: no 'axes' table (is it `bmg160-emu identify "
                              "--json` output?)")
    names = [str(name) for name in axes]
    if all(a in axes for a in AXES):
        chosen = list(AXES)
    else:
        by_letter = {a: [n for n in names if n.lower().endswith(a)] for a in AXES}
        if all(len(found) == 1 for found in by_letter.values()):
            chosen = [by_letter[a][0] for a in AXES]
        else:
            chosen = (names + [names[0]] * 3)[:3]
    return {a: axes[name] for a, name in zip(AXES, chosen)}


class NoiseDispersion:
    """Per-axis intervals of the dispersed parameters, drawn into noise profiles."""

    def __init__(self, intervals: Mapping[str, Mapping[str, Interval]], base: Any = "paper",
                 source: str = "") -> None:
        self.intervals = {a: dict(intervals[a]) for a in AXES}
        self.base = load_profile(base)
        self.source = source

    @classmethod
    def from_identification(cls, result: str | Path | Mapping[str, Any],
                            parameters: Sequence[str] = ("N", "B", "K"),
                            base: Any = "paper") -> NoiseDispersion:
        """From ``identify --json`` output (a path or the parsed mapping), its axes matched
        to x, y, z by :func:`identified_axes`; ``base`` gives what is not dispersed (T, the
        bias): the profile identified from the same record."""
        origin = "identification"
        parsed: Any = result
        if not isinstance(result, Mapping):
            origin = str(result)
            try:
                parsed = json.loads(Path(result).read_text())
            except OSError as exc:
                raise DispersionError(f"{origin}: cannot read: {exc.strerror}") from None
            except json.JSONDecodeError as exc:
                raise DispersionError(f"{origin}: not JSON (line {exc.lineno}: {exc.msg})") from None
        tables = identified_axes(parsed, origin)
        intervals: dict[str, dict[str, Interval]] = {}
        for axis in AXES:
            table = tables[axis]
            intervals[axis] = {}
            for key in parameters:
                if not isinstance(table, Mapping) or key not in table:
                    raise DispersionError(f"{origin}: axes.{axis} has no {key}")
                intervals[axis][key] = _interval(table[key], f"{origin}: axes.{axis}.{key}")
        return cls(intervals, base=base, source=origin)

    def draw(self, rng: np.random.Generator) -> tuple[dict[str, Any], dict[str, float]]:
        """A profile mapping for :class:`~bmg160_emu.adcs.rig.GyroSpec` and the drawn
        values (``"N_x"`` ...), in a fixed order so a seed always gives the same draws."""
        profile: dict[str, Any] = {"name": "dispersed",
                                   "description": f"N, B, K drawn within {self.source or 'CIs'}"}
        drawn: dict[str, float] = {}
        for axis, noise in zip(AXES, self.base.axes):
            table = {"N": noise.N, "B": noise.B, "T": noise.T, "K": noise.K, "bias": noise.bias}
            for key in sorted(self.intervals[axis]):
                value = self.intervals[axis][key].draw(rng)
                table[key] = value
                drawn[f"{key}_{axis}"] = value
            profile[axis] = table
        return profile, drawn
