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

This module reads the file and builds the :class:`Scenario`; the motions are
:mod:`bmg160_emu.adcs.motions`, the checks of single values
:mod:`bmg160_emu.adcs.scenario_values`, and a rate table's file
:mod:`bmg160_emu.adcs.rate_table`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.adcs.motions import (
    CallableMotion,
    ConstantRotation,
    Jitter,
    Motion,
    RateFunction,
    Rest,
    Slew,
    Table,
    Tumble,
    orbital_rate_dps,
)
from bmg160_emu.adcs.rate_table import load_rate_table
from bmg160_emu.adcs.scenario_values import (
    MAX_COMPONENT,
    ScenarioError,
    check_duration,
    finite_seconds,
    inertia_matrix,
    positive_key,
    unit_vector,
    vector3,
)
from bmg160_emu.io.errors import loads_toml, read_text
from bmg160_emu.limits import RATE_DPS

__all__ = ["Scenario", "ScenarioError", "load_scenario", "motion_from_dict",
           "scenario_from_dict"]


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
        check_duration(duration_s)
        return cls(duration_s=duration_s, motions=[CallableMotion(function=function)], name=name)

    @classmethod
    def constant(cls, rate_dps: Sequence[float], duration_s: float) -> Scenario:
        """A constant rotation (``(0, 0, 0)`` is rest)."""
        check_duration(duration_s)
        rate = vector3(rate_dps, "rate_dps")
        return cls(duration_s=duration_s, motions=[ConstantRotation(rate=rate)], name="constant")


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
    start = finite_seconds(entry.get("start_s", 0.0), f"{where}: start_s")
    end = entry.get("end_s")
    if end is not None:
        end = finite_seconds(end, f"{where}: end_s")
        if not end > start:
            raise ScenarioError(f"{where}: end_s must be after start_s")
    window: dict[str, Any] = {"start_s": start, "end_s": end}

    if kind == "rest":
        return Rest(**window)
    if kind == "constant":
        return ConstantRotation(rate=vector3(entry.get("rate_dps"), f"{where}: rate_dps"), **window)
    if kind == "orbital":
        if ("altitude_km" in entry) == ("period_s" in entry):
            raise ScenarioError(f"{where}: an orbital motion needs altitude_km or period_s")
        if "period_s" in entry:
            rate = 360.0 / positive_key(entry, "period_s", where)
        else:
            rate = orbital_rate_dps(float(entry["altitude_km"]))
        # Nadir pointing in LVLH: the body turns about the negative orbit normal (-y).
        axis = unit_vector(entry.get("axis", [0.0, -1.0, 0.0]), f"{where}: axis")
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
            axis=unit_vector(entry.get("axis"), f"{where}: axis"),
            angle_deg=float(angle),
            max_rate_dps=positive_key(entry, "max_rate_dps", where, maximum=MAX_COMPONENT),
            max_accel_dps2=positive_key(entry, "max_accel_dps2", where, maximum=MAX_COMPONENT),
            start_s=start,
        )
    if kind == "jitter":
        return Jitter(
            amplitude_dps=vector3(entry.get("amplitude_dps"), f"{where}: amplitude_dps"),
            frequency_hz=positive_key(entry, "frequency_hz", where, maximum=1e4),
            phase_deg=vector3(entry.get("phase_deg", [0.0, 0.0, 0.0]), f"{where}: phase_deg"),
            **window,
        )
    if kind == "tumble":
        damping = entry.get("damping_time_s")
        if damping is not None:
            damping = positive_key(entry, "damping_time_s", where)
        return Tumble(
            initial_rate_dps=vector3(entry.get("initial_rate_dps"), f"{where}: initial_rate_dps"),
            inertia_kg_m2=inertia_matrix(entry.get("inertia_kg_m2", [1.0, 1.0, 1.0]), where),
            damping_time_s=damping,
            horizon_s=min(duration_s, 600.0) + 10.0,  # then extended as far as asked
            **window,
        )
    # table
    data = load_rate_table(entry, where, base)
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
    duration = check_duration(data.get("duration_s"))
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
