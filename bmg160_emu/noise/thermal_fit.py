"""The bias of each axis as a polynomial of temperature, from a thermal record, with intervals.

Why: PX4 calibrates a cubic of gyro bias against temperature per axis (its TC_G* parameters)
from a thermal-chamber or flight log, and so does every ADCS team; the fit must come with
intervals a reviewer can trust. The gyro's own noise is strongly correlated in time (bias
instability, rate random walk), so an ordinary least-squares interval is far too narrow. This
fit is generalised least squares on block means with the covariance the noise model implies:

    y_i = mean rate over block i (duration D);  X_ik = mean of (T - T_ref)^k over block i
    y = X c + e,  Cov(e) = Sigma(N, GM poles, K)
    c = (X' S^-1 X)^-1 X' S^-1 y,   Cov(c) = (X' S^-1 X)^-1

Block-mean covariances (continuous-time forms; m = |i - j| blocks apart, a_i the start of
block i since the record's start):
  white, density N:           N^2 / D on the diagonal
  Gauss-Markov (q, T):        m = 0: 2 q^2 [T D - T^2 (1 - e^-D/T)] / D^2
                              m > 0: q^2 (T / D)^2 (1 - e^-D/T)^2 e^-(m-1) D / T
  random walk K (from 0 at the start; its offset goes into c0):
                              i < j: K^2 (a_i + D / 2),  i = j: K^2 (a_i + D / 3)

The noise terms come from a profile (an identification of a static record of the same unit) or,
when none is given, from an identification of the residuals of an ordinary fit (two-step
feasible GLS). Exports: our profile's ``errors`` table (``zero_rate_offset_dps``,
``bias_tc_dps_per_k``) and PX4's TC_G* parameters (rad/s; PX4 subtracts
X0 + X1 dT + X2 dT^2 + X3 dT^3, dT = T - TC_G0_TREF clamped to TMIN..TMAX).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

_Z = {0.90: 1.6448536269514722, 0.95: 1.959963984540054, 0.99: 2.5758293035489004}


class ThermalFitError(ValueError):
    """A record that cannot give a temperature fit; the message says why."""


@dataclass(frozen=True)
class NoiseTerms:
    """What the covariance needs: white density N (deg/s/sqrt(Hz)), Gauss-Markov poles
    (std q in deg/s, correlation time T in s) and rate random walk K (deg/s/sqrt(s))."""

    N: float
    poles: tuple[tuple[float, float], ...] = ()
    K: float = 0.0

    @classmethod
    def from_axis(cls, axis: Any) -> NoiseTerms:
        """From a profile axis (``N``, ``K`` and ``poles`` or ``B``/``T``)."""
        poles = getattr(axis, "poles", None)
        if poles:
            pairs = tuple((float(p[0]), float(p[1])) if isinstance(p, (tuple, list))
                          else (float(p.B), float(p.T)) for p in poles)
        elif getattr(axis, "B", 0.0) and getattr(axis, "T", 0.0):
            pairs = ((float(axis.B), float(axis.T)),)
        else:
            pairs = ()
        return cls(float(axis.N), pairs, float(getattr(axis, "K", 0.0)))


def block_covariance(terms: NoiseTerms, blocks: int, block_s: float) -> np.ndarray:
    """Covariance of ``blocks`` consecutive block means of ``block_s`` each (module docstring)."""
    d = block_s
    m = np.abs(np.subtract.outer(np.arange(blocks), np.arange(blocks)))
    cov = np.eye(blocks) * terms.N**2 / d
    for q, t in terms.poles:
        if q <= 0 or t <= 0:
            continue
        r = d / t
        one = 1.0 - math.exp(-r)
        diag = 2 * q**2 * (t * d - t**2 * one) / d**2
        off = q**2 * (t / d) ** 2 * one**2 * np.exp(-(np.maximum(m, 1) - 1) * r)
        cov += np.where(m == 0, diag, off)
    if terms.K > 0:
        starts = np.arange(blocks) * d
        first = np.minimum.outer(starts, starts)
        cov += terms.K**2 * (first + np.where(m == 0, d / 3, d / 2))
    return cov


@dataclass
class AxisThermalFit:
    """c0..c_order (deg/s/K^k about the reference temperature) with covariance and intervals."""

    coefficients: np.ndarray
    covariance: np.ndarray
    level: float
    reduced_chi2: float
    noise: NoiseTerms

    @property
    def standard_errors(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))

    @property
    def intervals(self) -> np.ndarray:
        """(order + 1, 2): symmetric intervals at ``level`` (the GLS estimate is normal)."""
        z = _Z[self.level]
        se = self.standard_errors
        return np.column_stack([self.coefficients - z * se, self.coefficients + z * se])


@dataclass
class ThermalFit:
    reference_c: float
    order: int
    block_s: float
    temperature_range_c: tuple[float, float]
    axes: list[AxisThermalFit] = field(default_factory=list)
    axis_names: tuple[str, ...] = ("x", "y", "z")

    def bias_dps(self, temperature_c: np.ndarray | float) -> np.ndarray:
        dt = np.asarray(temperature_c, dtype=float).reshape(-1, 1) - self.reference_c
        powers = dt ** np.arange(self.order + 1)
        return np.column_stack([powers @ a.coefficients for a in self.axes])

    def to_errors(self) -> dict[str, Any]:
        """A profile's ``errors`` table (bmg160_emu.noise.sensor_errors.SensorErrors)."""
        c = np.zeros((3, 4))
        for i, a in enumerate(self.axes[:3]):
            c[i, : self.order + 1] = a.coefficients
        return {"reference_temperature_c": self.reference_c,
                "zero_rate_offset_dps": c[:, 0].tolist(),
                "bias_tc_dps_per_k": c[:, 1:].tolist(),
                "source": f"thermal fit, order {self.order}, blocks of {self.block_s:g} s, "
                          f"{self.temperature_range_c[0]:.1f}..{self.temperature_range_c[1]:.1f}"
                          " deg C"}

    def px4_parameters(self, instance: int = 0, device_id: int = 0) -> dict[str, float | int]:
        """PX4's gyro thermal compensation parameters TC_G<instance>_*, in rad/s."""
        p = f"TC_G{instance}_"
        out: dict[str, float | int] = {"TC_G_ENABLE": 1, f"{p}ID": int(device_id),
                                       f"{p}TREF": self.reference_c,
                                       f"{p}TMIN": self.temperature_range_c[0],
                                       f"{p}TMAX": self.temperature_range_c[1]}
        for k in range(4):
            for i, a in enumerate(self.axes[:3]):
                value = a.coefficients[k] if k <= self.order else 0.0
                out[f"{p}X{k}_{i}"] = math.radians(float(value))
        return out

    def px4_params_file(self, instance: int = 0, device_id: int = 0) -> str:
        """QGroundControl's parameter file format (vehicle, component, name, value, type)."""
        lines = ["# Onboard parameters for Vehicle 1 (PX4 gyro thermal compensation, bmg160-emu)",
                 "# Vehicle-Id Component-Id Name Value Type"]
        for name, value in self.px4_parameters(instance, device_id).items():
            kind = 6 if isinstance(value, int) else 9  # MAV_PARAM_TYPE_INT32 / REAL32
            text = str(value) if isinstance(value, int) else f"{value:.9g}"
            lines.append(f"1\t1\t{name}\t{text}\t{kind}")
        return "\n".join(lines) + "\n"


def _block_means(values: np.ndarray, per_block: int, blocks: int) -> np.ndarray:
    return values[: per_block * blocks].reshape(blocks, per_block, -1).mean(axis=1)


def fit_bias_temperature(
    rate_dps: np.ndarray,
    temperature_c: np.ndarray,
    rate_hz: float,
    *,
    order: int = 3,
    reference_c: float | None = None,
    block_s: float = 60.0,
    noise: Sequence[Any] | None = None,
    level: float = 0.95,
) -> ThermalFit:
    """Fit each axis's bias as a polynomial of ``order`` (0..3) in temperature.

    ``rate_dps`` (n, k) of a unit at rest, ``temperature_c`` (n,) its die temperature, both at
    ``rate_hz``. ``reference_c`` defaults to the mid temperature of the record. ``noise``: one
    profile axis or :class:`NoiseTerms` per rate column (default: identified from the residuals
    of an ordinary fit)."""
    rate = np.asarray(rate_dps, dtype=float)
    rate = rate.reshape(-1, 1) if rate.ndim == 1 else rate
    temps = np.asarray(temperature_c, dtype=float).reshape(-1)
    if rate.shape[0] != temps.shape[0]:
        raise ThermalFitError(f"{rate.shape[0]} rate samples but {temps.shape[0]} temperatures")
    if not np.all(np.isfinite(rate)) or not np.all(np.isfinite(temps)):
        raise ThermalFitError("the record holds non-finite rates or temperatures")
    if order not in (0, 1, 2, 3):
        raise ThermalFitError(f"order must be 0..3 (PX4 fits a cubic), not {order!r}")
    if level not in _Z:
        raise ThermalFitError(f"level must be one of {sorted(_Z)}, not {level!r}")
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise ThermalFitError(f"rate_hz must be positive, not {rate_hz!r}")
    per_block = max(1, round(block_s * rate_hz))
    blocks = rate.shape[0] // per_block
    if blocks < 4 * (order + 1):
        raise ThermalFitError(
            f"{blocks} blocks of {block_s:g} s are too few for an order-{order} fit: record at "
            f"least {4 * (order + 1) * block_s:g} s or shorten the blocks")
    span = (float(temps.min()), float(temps.max()))
    if span[1] - span[0] < 1.0:
        raise ThermalFitError(f"the temperature spans only {span[1] - span[0]:.2f} K: a "
                              "temperature fit needs a thermal cycle or a chamber ramp")
    ref = float(np.mean(span)) if reference_c is None else float(reference_c)
    d = per_block / rate_hz
    y = _block_means(rate, per_block, blocks)
    # the block mean of each power of dT (not the power of the mean dT: the temperature moves
    # within a block, and the bias follows it sample by sample)
    design = _block_means((temps - ref).reshape(-1, 1) ** np.arange(order + 1), per_block, blocks)
    rank = int(np.linalg.matrix_rank(design))
    if rank < order + 1:  # e.g. two temperature plateaus under a cubic: no unique fit
        raise ThermalFitError(f"the block temperatures determine only {rank} of the "
                              f"{order + 1} coefficients of an order-{order} fit: record a "
                              "ramp or lower the order")
    fit = ThermalFit(ref, order, d, span)
    for axis in range(rate.shape[1]):
        terms = _terms_for(axis, noise, rate[:, axis], temps, rate_hz, design, y[:, axis],
                           ref, order, per_block, blocks)
        cov = block_covariance(terms, blocks, d)
        chol = np.linalg.cholesky(cov)
        a = np.linalg.solve(chol, design)
        b = np.linalg.solve(chol, y[:, axis])
        coef, *_ = np.linalg.lstsq(a, b, rcond=None)
        covariance = np.linalg.inv(a.T @ a)
        if not np.all(np.diag(covariance) > 0):  # near-singular: rounding made a variance < 0
            raise ThermalFitError(f"the order-{order} fit is too ill-conditioned for the "
                                  "temperatures recorded: record a wider ramp or lower the order")
        resid = b - a @ coef
        chi2 = float(resid @ resid) / max(blocks - order - 1, 1)
        fit.axes.append(AxisThermalFit(coef, covariance, level, chi2, terms))
    return fit


def _terms_for(axis, noise, rate, temps, rate_hz, design, y, ref, order, per_block, blocks):
    if noise is not None:
        item = noise[axis]
        return item if isinstance(item, NoiseTerms) else NoiseTerms.from_axis(item)
    # two-step: an ordinary fit, then the noise identified from what it leaves
    from bmg160_emu.noise.identify import identify_axis

    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    powers = (temps - ref).reshape(-1, 1) ** np.arange(order + 1)
    residual = rate - powers @ coef
    return NoiseTerms.from_axis(identify_axis(residual, rate_hz).to_axis_noise())
