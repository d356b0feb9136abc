"""The deterministic error budget of one gyro unit: what a flight engineer calibrates.

The stochastic terms (N, B/T, K) live in the noise engine; these are the errors a data sheet
lists as tolerances and a thermal chamber measures (issue 16). All are off unless set. For a
sample with sensor-frame true rate w (deg/s), die temperature T (deg C) and acceleration a
(g, sensor frame), with dT = T - reference_temperature_c, axis i reads

    w_out_i = (1 + s_i + s_T,i dT) * (w_i + sum_j C_ij w_j) + NL_i(w_i)
              + b0_i + b_on,i + c1_i dT + c2_i dT^2 + c3_i dT^3 + sum_j G_ij a_j

  s      scale-factor error, a fraction (data sheet "sensitivity tolerance", %)
  s_T    sensitivity change with temperature, 1/K (data sheet TCS, %/K)
  C      cross-axis sensitivity, off-diagonal fractions (data sheet "cross axis sensitivity")
  NL     nonlinearity: NL_i(w) = nl_i FS (x^3 - 0.6 x) / 0.4, x = w / FS, whose largest
         deviation from the least-squares straight line over the range is |nl_i| FS (the data
         sheet's "best fit straight line" %FS figure; the sign is the bow's direction); FS is
         the selected range in deg/s
  b0     zero-rate offset of the unit, deg/s (data sheet "zero-rate offset")
  b_on   turn-on bias: drawn afresh at every power-on and soft reset (TurnOnBias)
  c1..c3 bias temperature polynomial, deg/s/K^k (data sheet TCO is c1; PX4's TC_G* fit c0..c3)
  G      g-sensitivity, deg/s per g (data sheet "g-sensitivity")

The chip applies them after mounting, scale factor and misalignment of the rig and before its
low-pass filter (they are errors of the sensing element), then adds noise (docs/error-budget.md).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

# Largest |x^3 - 0.6 x| on [-1, 1] (at x = +-1): 0.6 x is the least-squares line of x^3 there,
# so dividing by it makes nl the largest deviation from the best-fit straight line.
_NL_PEAK = 0.4

# Bounds that keep every output finite and every term physical (a value outside is refused):
# generous beyond any MEMS data sheet (BMG160: offset +-1 deg/s, TCO +-0.015 deg/s/K).
LIMITS = {
    "zero_rate_offset_dps": 1000.0,
    "bias_tc_dps_per_k": 100.0,
    "scale_factor_error": 0.5,
    "sensitivity_tc_per_k": 0.01,
    "nonlinearity_fs": 0.1,
    "cross_axis": 0.5,
    "g_sensitivity_dps_per_g": 100.0,
    "turn_on_bias_sigma_dps": 100.0,
    "temperature_c": 200.0,  # |T - T_ref| used by the polynomial
}


def _vector(value: Any, name: str, limit: float) -> tuple[float, float, float]:
    array = np.broadcast_to(np.asarray(value, dtype=float), (3,))
    if not np.all(np.isfinite(array)) or np.any(np.abs(array) > limit):
        raise ValueError(f"{name} must be 3 finite numbers within +-{limit:g}, not {value!r}")
    return (float(array[0]), float(array[1]), float(array[2]))


def _matrix(value: Any, name: str, limit: float) -> tuple[tuple[float, ...], ...]:
    array = np.asarray(value, dtype=float)
    if array.shape != (3, 3) or not np.all(np.isfinite(array)) or np.any(np.abs(array) > limit):
        raise ValueError(f"{name} must be a finite 3x3 matrix within +-{limit:g}, not {value!r}")
    return tuple(tuple(float(v) for v in row) for row in array)


_ZERO3 = (0.0, 0.0, 0.0)
_ZERO33 = (_ZERO3, _ZERO3, _ZERO3)


@dataclass(frozen=True)
class SensorErrors:
    """One unit's deterministic errors (see the module docstring for the model and units)."""

    reference_temperature_c: float = 25.0
    zero_rate_offset_dps: tuple[float, float, float] = _ZERO3
    bias_tc_dps_per_k: tuple[tuple[float, float, float], ...] = (_ZERO3, _ZERO3, _ZERO3)
    scale_factor_error: tuple[float, float, float] = _ZERO3
    sensitivity_tc_per_k: tuple[float, float, float] = _ZERO3
    nonlinearity_fs: tuple[float, float, float] = _ZERO3
    cross_axis: tuple[tuple[float, ...], ...] = _ZERO33
    g_sensitivity_dps_per_g: tuple[tuple[float, ...], ...] = _ZERO33
    turn_on_bias_sigma_dps: tuple[float, float, float] = _ZERO3
    source: str = ""  # where the numbers come from (a data sheet section, a fit)

    def __post_init__(self) -> None:
        t_ref = float(self.reference_temperature_c)
        if not math.isfinite(t_ref) or abs(t_ref) > LIMITS["temperature_c"]:
            raise ValueError(f"reference_temperature_c must be finite, not {t_ref!r}")
        object.__setattr__(self, "reference_temperature_c", t_ref)
        for name in ("zero_rate_offset_dps", "scale_factor_error", "sensitivity_tc_per_k",
                     "nonlinearity_fs", "turn_on_bias_sigma_dps"):
            object.__setattr__(self, name, _vector(getattr(self, name), name, LIMITS[name]))
        if any(s < 0 for s in self.turn_on_bias_sigma_dps):
            raise ValueError("turn_on_bias_sigma_dps must not be negative")
        tc = np.asarray(self.bias_tc_dps_per_k, dtype=float)
        if tc.ndim == 1:  # one coefficient row per axis given as c1 only
            tc = tc.reshape(3, 1)
        if tc.ndim != 2 or tc.shape[0] != 3 or not 1 <= tc.shape[1] <= 3:
            raise ValueError("bias_tc_dps_per_k must hold, per axis, c1 or c1, c2 or c1, c2, c3 "
                             "(deg/s/K^k; a cubic at most)")
        tc = np.pad(tc, ((0, 0), (0, 3 - tc.shape[1])))
        if not np.all(np.isfinite(tc)) or np.any(np.abs(tc) > LIMITS["bias_tc_dps_per_k"]):
            raise ValueError("bias_tc_dps_per_k must be finite and within "
                             f"+-{LIMITS['bias_tc_dps_per_k']:g}")
        object.__setattr__(self, "bias_tc_dps_per_k", tuple(tuple(map(float, r)) for r in tc))
        cross = _matrix(self.cross_axis, "cross_axis", LIMITS["cross_axis"])
        if any(cross[i][i] for i in range(3)):
            raise ValueError("cross_axis has no diagonal (that is scale_factor_error): give 0 there")
        object.__setattr__(self, "cross_axis", cross)
        object.__setattr__(self, "g_sensitivity_dps_per_g", _matrix(
            self.g_sensitivity_dps_per_g, "g_sensitivity_dps_per_g",
            LIMITS["g_sensitivity_dps_per_g"]))

    # ------------------------------------------------------------------ queries

    @property
    def active(self) -> bool:
        """Any term set (a chip without one skips the whole stage)."""
        return any(np.any(np.asarray(getattr(self, f.name), dtype=float))
                   for f in fields(self) if f.name not in ("reference_temperature_c", "source"))

    @property
    def needs_acceleration(self) -> bool:
        return bool(np.any(np.asarray(self.g_sensitivity_dps_per_g)))

    def bias_dps(self, temperature_c: np.ndarray | float) -> np.ndarray:
        """Zero-rate output at ``temperature_c`` (no turn-on bias): (n, 3) deg/s."""
        dt = np.clip(np.asarray(temperature_c, dtype=float).reshape(-1, 1)
                     - self.reference_temperature_c,
                     -LIMITS["temperature_c"], LIMITS["temperature_c"])
        c = np.asarray(self.bias_tc_dps_per_k)  # (3 axes, c1..c3)
        return (np.asarray(self.zero_rate_offset_dps)
                + dt * c[:, 0] + dt**2 * c[:, 1] + dt**3 * c[:, 2])

    # ------------------------------------------------------------------ the data path

    def apply(
        self,
        rate_dps: np.ndarray,
        temperature_c: np.ndarray | float,
        full_scale_dps: float,
        acceleration_g: np.ndarray | None = None,
        turn_on_bias_dps: Sequence[float] | np.ndarray = _ZERO3,
    ) -> np.ndarray:
        """The sensor-frame rates ``rate_dps`` (n, 3) as this unit senses them."""
        w = np.asarray(rate_dps, dtype=float).reshape(-1, 3)
        n = w.shape[0]
        temps = np.broadcast_to(np.asarray(temperature_c, dtype=float).reshape(-1), (n,))
        dt = np.clip(temps - self.reference_temperature_c,
                     -LIMITS["temperature_c"], LIMITS["temperature_c"]).reshape(-1, 1)
        cross = np.asarray(self.cross_axis)
        coupled = w + w @ cross.T if np.any(cross) else w
        gain = 1.0 + np.asarray(self.scale_factor_error) + dt * np.asarray(
            self.sensitivity_tc_per_k)
        out = gain * coupled
        nl = np.asarray(self.nonlinearity_fs)
        if np.any(nl):
            x = np.clip(w / full_scale_dps, -1.0, 1.0)
            out = out + nl * full_scale_dps * (x**3 - 0.6 * x) / _NL_PEAK
        out = out + self.bias_dps(temps) + np.asarray(turn_on_bias_dps, dtype=float)
        if acceleration_g is not None and self.needs_acceleration:
            a = np.broadcast_to(np.asarray(acceleration_g, dtype=float).reshape(-1, 3), (n, 3))
            out = out + a @ np.asarray(self.g_sensitivity_dps_per_g).T
        return out

    # ------------------------------------------------------------------ files

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and floats (a profile's ``[errors]`` table, a trace header)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = value if isinstance(value, (float, str)) else np.asarray(
                value, dtype=float).tolist()
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "errors") -> SensorErrors:
        """From a profile's ``[errors]`` table; unknown keys and bad values are ValueErrors
        naming ``where`` and the key."""
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"{where}: unknown keys {sorted(unknown)} (known: {sorted(known)})")
        try:
            return cls(**dict(data))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: {exc}") from None

    def with_(self, **changes: Any) -> SensorErrors:
        return replace(self, **changes)


NO_ERRORS = SensorErrors()


@dataclass
class TurnOnBias:
    """A fresh bias at every power-on and soft reset, drawn from the seed: N(0, sigma) per axis
    (deg/s), the k-th power cycle of a seed always giving the same value."""

    sigma_dps: tuple[float, float, float]
    seed: int | None
    draws: int = field(default=0, init=False)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(
            None if self.seed is None else np.random.SeedSequence([int(self.seed), 0x7B1A5]))

    def next(self) -> np.ndarray:
        """The bias of the next power cycle, deg/s (3,)."""
        self.draws += 1
        return self._rng.standard_normal(3) * np.asarray(self.sigma_dps)
