"""Units of a part: each unit's deterministic errors drawn from the data sheet's tolerances.

A GNC team's Monte Carlo flies many units of a part, not one ideal chip. ``draw_unit(part,
seed, unit)`` gives unit ``unit`` of a production lot reproducibly from ``seed``: its zero-rate
offset, sensitivity error, temperature coefficients, cross-axis and g-sensitivity.

Distribution assumed for every figure: a normal distribution with mean 0, because Bosch
Sensortec states that its data sheets' *typical* values are one standard deviation of the
production spread and their *min/max* values three (Bosch Sensortec community forum, "BMI270
gyroscope x axis zero-rate offset out of spec", answer by Bosch staff). A typical figure
``+-t`` is therefore sigma = t; a max figure ``m`` is sigma = m / 3. Each cross-axis term and
each g-sensitivity term is drawn independently.

The figures (BMG160 data sheet BST-BMG160-DS000-09, table 1 "electrical and mechanical
specification"; the same values stand in the BMI088 data sheet BST-BMI088-DS001 for its
gyroscope, table 5, which shares the die family): sensitivity tolerance +-1 % (typ),
sensitivity change over temperature +-0.03 %/K (typ), nonlinearity +-0.05 %FS (typ, best fit
straight line), g-sensitivity 0.1 deg/s/g (max), zero-rate offset +-1 deg/s (typ),
zero-rate offset change over temperature +-0.015 deg/s/K (typ), cross-axis sensitivity +-1 %
(typ). The data sheet gives no figure for turn-on-to-turn-on bias repeatability or for the
curvature of the offset over temperature: those stay 0 in a drawn unit unless the caller sets
them (``turn_on_bias_sigma_dps``, ``bias_curvature_sigma``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bmg160_emu.noise.sensor_errors import SensorErrors

_DS = "BMG160 data sheet BST-BMG160-DS000-09 table 1 (= BMI088 data sheet table 5, gyroscope)"


@dataclass(frozen=True)
class Tolerance:
    """One data sheet figure: ``value`` in ``unit``, ``kind`` "typ" (1 sigma) or "max"
    (3 sigma), and where it is printed."""

    value: float
    kind: str
    unit: str
    source: str = _DS

    @property
    def sigma(self) -> float:
        """Standard deviation of the production spread, in the model's unit (see below)."""
        return self.value / (3.0 if self.kind == "max" else 1.0) * _TO_MODEL_UNIT[self.unit]


# data sheet unit -> the SensorErrors unit
_TO_MODEL_UNIT = {"deg/s": 1.0, "deg/s/K": 1.0, "%": 0.01, "%/K": 0.01, "%FS": 0.01,
                  "deg/s/g": 1.0}


@dataclass(frozen=True)
class PartTolerances:
    """The production spread of a part's deterministic errors."""

    part: str
    zero_rate_offset: Tolerance
    offset_tc: Tolerance
    sensitivity: Tolerance
    sensitivity_tc: Tolerance
    nonlinearity: Tolerance
    cross_axis: Tolerance
    g_sensitivity: Tolerance
    reference_temperature_c: float = 25.0  # the data sheet's "TA = 25 deg C" conditions


BMG160_TOLERANCES = PartTolerances(
    part="bmg160",
    zero_rate_offset=Tolerance(1.0, "typ", "deg/s"),
    offset_tc=Tolerance(0.015, "typ", "deg/s/K"),
    sensitivity=Tolerance(1.0, "typ", "%"),
    sensitivity_tc=Tolerance(0.03, "typ", "%/K"),
    nonlinearity=Tolerance(0.05, "typ", "%FS"),
    cross_axis=Tolerance(1.0, "typ", "%"),
    g_sensitivity=Tolerance(0.1, "max", "deg/s/g"),
)

PARTS = {"bmg160": BMG160_TOLERANCES}


def draw_unit(
    seed: int,
    unit: int,
    tolerances: PartTolerances = BMG160_TOLERANCES,
    *,
    turn_on_bias_sigma_dps: float = 0.0,
    bias_curvature_sigma: tuple[float, float] = (0.0, 0.0),
) -> SensorErrors:
    """Unit ``unit`` (>= 0) of the lot ``seed``: the same pair always gives the same unit, and
    units are independent of each other. ``bias_curvature_sigma`` (deg/s/K^2, deg/s/K^3) adds
    quadratic and cubic offset terms the data sheet does not give."""
    if isinstance(unit, bool) or not isinstance(unit, (int, np.integer)) or unit < 0:
        raise ValueError(f"unit must be an integer >= 0, not {unit!r}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), int(unit), 0x0D1CE]))
    t = tolerances

    def normal(tol_sigma: float, shape: tuple[int, ...] = (3,)) -> np.ndarray:
        return rng.standard_normal(shape) * tol_sigma

    offset = normal(t.zero_rate_offset.sigma)
    c1 = normal(t.offset_tc.sigma)
    c2 = normal(bias_curvature_sigma[0])
    c3 = normal(bias_curvature_sigma[1])
    cross = normal(t.cross_axis.sigma, (3, 3))
    np.fill_diagonal(cross, 0.0)
    return SensorErrors(
        reference_temperature_c=t.reference_temperature_c,
        zero_rate_offset_dps=tuple(offset),
        bias_tc_dps_per_k=tuple(zip(c1, c2, c3)),
        scale_factor_error=tuple(normal(t.sensitivity.sigma)),
        sensitivity_tc_per_k=tuple(normal(t.sensitivity_tc.sigma)),
        nonlinearity_fs=tuple(normal(t.nonlinearity.sigma)),
        cross_axis=tuple(map(tuple, cross)),
        g_sensitivity_dps_per_g=tuple(map(tuple, normal(t.g_sensitivity.sigma, (3, 3)))),
        turn_on_bias_sigma_dps=(turn_on_bias_sigma_dps,) * 3,
        source=(f"unit {unit} of lot {seed}, drawn from {t.part} tolerances "
                f"({t.zero_rate_offset.source})"),
    )
