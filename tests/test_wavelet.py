"""Haar wavelet variance: the estimator, its relation to the Allan variance, its covariance."""

from __future__ import annotations

import math

import allantools
import numpy as np
import pytest

from bmg160_emu.noise.wavelet import (
    WaveletVariance,
    dyadic_scales,
    haar_squared_gain,
    haar_wv,
    wv_covariance,
)


def _direct_wv(x: np.ndarray, m: int) -> float:
    """The definition, coefficient by coefficient: half the difference of adjacent m-means."""
    coeffs = [
        0.5 * (x[t - m + 1 : t + 1].mean() - x[t - 2 * m + 1 : t - m + 1].mean())
        for t in range(2 * m - 1, x.size)
    ]
    return float(np.mean(np.square(coeffs)))


def test_estimator_matches_the_definition():
    rng = np.random.default_rng(1)
    x = 3.0 + rng.standard_normal(300) + np.cumsum(rng.standard_normal(300)) * 0.1
    wv = haar_wv(x, 10.0)
    assert list(wv.m) == [1, 2, 4, 8, 16, 32, 64, 128]
    assert list(wv.n_coeffs) == [300 - 2 * m + 1 for m in wv.m]
    assert wv.taus_s == pytest.approx(wv.m / 10.0)
    for m, value in zip(wv.m, wv.wv):
        assert value == pytest.approx(_direct_wv(x, int(m)), rel=1e-10)


def test_allan_variance_is_twice_the_haar_wavelet_variance():
    # AVAR(tau) = 2 nu^2(tau) at tau = m dt, m = 2^j: the same overlapping differences
    rng = np.random.default_rng(2)
    x = rng.standard_normal(50_000) * 0.25 + np.cumsum(rng.standard_normal(50_000)) * 1e-3
    taus, adev, _err, n = allantools.oadev(x, rate=200.0, data_type="freq", taus="octave")
    wv = haar_wv(x, 200.0)
    assert wv.taus_s == pytest.approx(np.asarray(taus))
    assert list(wv.n_coeffs) == [int(k) for k in n]
    assert np.asarray(adev) ** 2 == pytest.approx(2.0 * wv.wv, rel=1e-9)
    assert wv.avar == pytest.approx(2.0 * wv.wv)


def test_scales_keep_the_requested_share_of_coefficients():
    assert list(dyadic_scales(16)) == [1, 2, 4, 8]  # M = 16 - 16 + 1 = 1 at m = 8
    assert list(dyadic_scales(16, 0.5)) == [1, 2, 4]  # M >= 8
    assert dyadic_scales(1).size == 0
    wv = haar_wv(np.arange(64.0) % 5, 1.0, 0.5)
    assert (wv.n_coeffs >= 32).all()
    with pytest.raises(ValueError, match="no dyadic scale"):
        haar_wv(np.ones(1), 1.0)
    with pytest.raises(ValueError, match="one axis"):
        haar_wv(np.ones((10, 2)), 1.0)


def test_squared_gain_is_the_filters_transfer_function():
    m = 4
    h = np.r_[np.full(m, 1.0), np.full(m, -1.0)] / (2 * m)
    f = np.linspace(0.01, 0.49, 7)
    direct = np.abs(np.exp(-2j * np.pi * np.outer(f, np.arange(2 * m))) @ h) ** 2
    assert haar_squared_gain(f, m) == pytest.approx(direct, rel=1e-12)


@pytest.mark.parametrize(
    ("name", "spectrum"),
    [
        ("white", lambda f: np.ones_like(f)),
        ("random walk", lambda f: 1.0 / (4.0 * np.sin(np.pi * f) ** 2)),
    ],
)
def test_covariance_matches_monte_carlo(name, spectrum):
    # 2000 records of 4096 samples: the Monte Carlo variance of each scale's estimate has a
    # relative sd of about sqrt(2 / 2000) (1 + correlation) < 5 %; 15 % is three of those.
    # Correlations between neighbouring scales (0.5 white, 0.85 random walk): Monte Carlo sd
    # (1 - rho^2) / sqrt(2000) <= 0.017, bound 0.06 (3.5 sd); the top pair (M = n / 2) carries
    # the finite-record approximation (FINITE_KAPPA), measured 0.085 off for the random walk:
    # bound 0.1 there.
    rng = np.random.default_rng(11)
    n, reps = 4096, 2000
    draws = []
    for _ in range(reps):
        x = rng.standard_normal(n)
        if name == "random walk":
            x = np.cumsum(x)
        draws.append(haar_wv(x, 1.0, 0.5).wv)
    mc = np.cov(np.array(draws).T)
    ref = haar_wv(np.zeros(n) + np.arange(n) % 3, 1.0, 0.5)
    omega = wv_covariance(ref.m, ref.n_coeffs, spectrum)
    assert np.diag(omega) == pytest.approx(np.diag(mc), rel=0.15)
    corr = omega / np.sqrt(np.outer(np.diag(omega), np.diag(omega)))
    corr_mc = mc / np.sqrt(np.outer(np.diag(mc), np.diag(mc)))
    idx = np.arange(ref.m.size - 1)
    off = np.abs(corr[idx, idx + 1] - corr_mc[idx, idx + 1])
    assert off[:-1].max() < 0.06 and off[-1] < 0.1


def test_white_noise_variance_has_the_known_closed_form():
    # unit white noise at m = 1: W_t = (x_t - x_t-1) / 2 has autocovariance c(0) = 1/2,
    # c(+-1) = -1/4; the estimate's variance is 2 sum_h c(h)^2 / M = 2 (1/4 + 2/16) / M,
    # times the finite-record factor 1 - m / (3 M)
    m = np.array([1])
    omega = wv_covariance(m, np.array([1000]), lambda f: np.ones_like(f))
    assert omega[0, 0] == pytest.approx(2.0 * (0.25 + 2 * 0.0625) / 1000 * (1 - 1 / 3000), rel=1e-3)


def test_chi_square_interval_brackets_the_estimate():
    rng = np.random.default_rng(3)
    wv = haar_wv(rng.standard_normal(10_000), 1.0)
    lo, hi = wv.ci(0.95)
    assert (lo < wv.wv).all() and (wv.wv < hi).all()
    assert isinstance(wv.up_to(8), WaveletVariance) and wv.up_to(8).m[-1] == 8
    assert math.isclose(wv.edf()[0], wv.n_coeffs[0])
