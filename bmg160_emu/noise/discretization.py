"""Per-sample coefficients of the noise recursion for one axis at one output data rate.

Each axis output is, per sample k (period dt):

    white(k) = white_std * w_N(k)
    gm(k)    = alpha * gm(k-1) + gm_gain * w_B(k)          first-order Gauss-Markov, per term
    rw(k)    = rw(k-1) + rw_step * w_K(k)                  random walk
    q(k)     = Q (w_Q(k) - w_Q(k-1)) / dt                  angle quantization (optional)
    ramp(k)  = R t_k                                       rate ramp (optional)
    out(k)   = white + sum of gm terms + rw [+ q] [+ ramp] + bias

A profile axis holds any number of Gauss-Markov terms (B_i, T_i): its B, T and its ``gm``
list (profile.py); each is its own recursion with its own normals.

Two discretizations (docs/noise-engine.md):

- "physical": white N/sqrt(dt), random walk K sqrt(dt), Gauss-Markov alpha = exp(-dt/T) with
  gain B sqrt(1 - alpha^2) so that its stationary std is B. Identifying the output gives back
  N, B, T, K at every rate.
- "paper": El Fatimi et al. 2023 eqs. (11)-(17) with dt = 1/rate: the same Gauss-Markov term
  (b_d sigma_B = B sqrt(1 - alpha^2)), random-walk step K dt sigma_K, white std
  sigma_N = sqrt(sigma_gyro^2 - B^2 - (K dt sigma_K)^2). At 200 Hz these are the paper's
  constants; at other rates they are the paper's formulas evaluated at that dt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bmg160_emu.noise.gauss_markov import (
    PoleCoefficients,
    ResonanceCoefficients,
    pole_coefficients,
    resonance_coefficients,
    walk_coefficients,
)
from bmg160_emu.noise.profile import AxisNoise, ProfileError

MODES = ("physical", "paper")

# Output data rates of the BMG160 (register spec section 5.3, BW register 0x10).
SUPPORTED_RATES_HZ = (100.0, 200.0, 400.0, 1000.0, 2000.0)


@dataclass(frozen=True)
class AxisCoefficients:
    """Per-sample coefficients of one axis at one sample period."""

    dt: float
    white_std: float
    alpha: float  # of the B, T term (the firmware's single term)
    gm_gain: float
    rw_step: float
    quant_scale: float  # Q / dt
    ramp_slope: float  # R, deg/s per s
    bias: float
    poles: tuple[PoleCoefficients, ...] = ()  # every Gauss-Markov term, B, T first
    walk: PoleCoefficients | None = None  # the random walk's block tables (rw_step)
    # each resonator of the axis's bands; None: its centre is not below this rate's Nyquist
    # frequency (it is left out there: a sampled output cannot carry it)
    bands: tuple[ResonanceCoefficients | None, ...] = ()


def check_rate(rate_hz: float, own_rate_hz: float | None = None) -> float:
    """The rate as float if the BMG160 offers it, or it is ``own_rate_hz`` (the rate a
    profile was identified at, its [output] rate_hz: a user's sensor runs at its own rate,
    250 Hz for a PX4 autopilot's, 104 or 833 Hz for ST's), else a clear ValueError."""
    try:
        rate = float(rate_hz)
    except (TypeError, ValueError):
        raise ValueError(f"output data rate must be a number in Hz, got {rate_hz!r}") from None
    if own_rate_hz is not None and math.isfinite(rate) and rate > 0 and abs(
            rate - own_rate_hz) <= 1e-9 * own_rate_hz:
        return float(own_rate_hz)
    if rate not in SUPPORTED_RATES_HZ:
        offered = ", ".join(f"{r:g}" for r in SUPPORTED_RATES_HZ)
        own = (f", and this profile runs at the rate it was identified at, {own_rate_hz:g}"
               if own_rate_hz is not None and own_rate_hz not in SUPPORTED_RATES_HZ else "")
        raise ValueError(
            f"unsupported output data rate {rate_hz!r} Hz: the BMG160 offers {offered}{own}"
        )
    return rate


def check_mode(mode: str) -> str:
    if mode not in MODES:
        raise ValueError(f"unknown noise mode {mode!r}: use 'physical' or 'paper'")
    return mode


def gauss_markov_alpha(dt: float, T: float) -> float:
    """alpha = exp(-dt/T) (paper eq. 11); 0 when T = 0 (no correlation)."""
    return math.exp(-dt / T) if T > 0 else 0.0


def paper_b_d(dt: float, T: float) -> float:
    """b_d = integral_0^dt exp(-t/T) dt = T (1 - alpha) (paper eq. 11)."""
    return T * (1.0 - gauss_markov_alpha(dt, T))


def paper_sigma_B(B: float, dt: float, T: float) -> float:
    """sigma_B = B sqrt(1 - alpha^2) / b_d (paper eq. 12): the drive making std(gm) = B."""
    alpha = gauss_markov_alpha(dt, T)
    return B * math.sqrt(1.0 - alpha * alpha) / paper_b_d(dt, T)


def paper_sigma_N(sigma_gyro: float, B: float, K: float, dt: float, sigma_K: float) -> float:
    """sigma_N = sqrt(sigma_gyro^2 - B^2 - (K dt sigma_K)^2) (paper eq. 16)."""
    radicand = sigma_gyro**2 - B**2 - (K * dt * sigma_K) ** 2
    if radicand < 0:
        raise ProfileError(
            f"paper mode: sigma_gyro = {sigma_gyro} deg/s is smaller than the B and K terms "
            "it must contain (paper eq. 16)"
        )
    return math.sqrt(radicand)


def axis_coefficients(axis: AxisNoise, rate_hz: float, mode: str) -> AxisCoefficients:
    """Coefficients of one axis at rate_hz in the given mode (module docstring)."""
    dt = 1.0 / rate_hz
    alpha = gauss_markov_alpha(dt, axis.T)
    gm_gain = axis.B * math.sqrt(1.0 - alpha * alpha)
    if mode == "physical":
        white_std = axis.N / math.sqrt(dt)
        rw_step = axis.K * math.sqrt(dt)
    elif mode == "paper":
        if axis.sigma_gyro is None or axis.sigma_K is None:
            raise ProfileError(
                "paper mode needs sigma_gyro and sigma_K in every axis of the profile "
                "(the built-in 'paper' profile has them)"
            )
        rw_step = axis.K * dt * axis.sigma_K
        # eq. 16 with the variance of every Gauss-Markov term (one term: the paper's B)
        b_total = math.sqrt(sum(B * B for B, _ in axis.gauss_markov_terms))
        white_std = paper_sigma_N(axis.sigma_gyro, b_total, axis.K, dt, axis.sigma_K)
    else:
        check_mode(mode)
        raise AssertionError  # unreachable
    poles = []
    for B, T in axis.gauss_markov_terms:
        poles.append(pole_coefficients(B, dt, T))
    return AxisCoefficients(
        dt=dt,
        white_std=white_std,
        alpha=alpha,
        gm_gain=gm_gain,
        rw_step=rw_step,
        quant_scale=axis.Q / dt,
        ramp_slope=axis.R,
        bias=axis.bias,
        poles=tuple(poles),
        walk=walk_coefficients(rw_step) if axis.K > 0 else None,
        bands=tuple(resonance_coefficients(f, w, B, dt) for f, w, B in axis.resonators),
    )
