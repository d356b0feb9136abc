"""Theoretical Haar wavelet variance of each process, against exact sums and Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bmg160_emu.noise import gmwm
from bmg160_emu.noise.allan import composite_avar
from bmg160_emu.noise.wavelet import haar_wv

DT = 0.005  # 200 Hz
M = 2 ** np.arange(0, 10)


def _haar(m: int) -> np.ndarray:
    """Haar MODWT filter at scale m: W_t = sum_k h_k x_(t-k)."""
    return np.r_[np.full(m, 1.0), np.full(m, -1.0)] / (2 * m)


def _filter_variance_of_stationary(m: int, acov) -> float:
    """var(sum_k h_k x_(t-k)) = sum_k sum_l h_k h_l gamma(k - l), computed term by term."""
    h = _haar(m)
    lag = np.subtract.outer(np.arange(h.size), np.arange(h.size))
    return float(h @ acov(np.abs(lag)) @ h)


def test_white_noise_matches_the_filter_sum():
    N = 0.0178
    sigma2 = N * N / DT
    for m in M[:8]:
        direct = _filter_variance_of_stationary(int(m), lambda h: sigma2 * (h == 0))
        assert gmwm.wv_white(np.array([m]), DT, N)[0] == pytest.approx(direct, rel=1e-12)


@pytest.mark.parametrize("T", [0.004, 0.05, 1.0, 33.9, 1e4])
def test_gauss_markov_matches_the_filter_sum(T):
    # both branches (Taylor series where (2m + 1) dt / T < 1, closed form beyond) against
    # the exact double sum over the AR(1) autocovariance B^2 phi^|h|
    B = 4e-3
    phi = math.exp(-DT / T)
    for m in M[:8]:
        direct = _filter_variance_of_stationary(int(m), lambda h: B * B * phi**h)
        got = gmwm.wv_gauss_markov(np.array([m]), DT, B, T)[0]
        # the double sum cancels to O((m dt / T)^3) of B^2: it keeps fewer digits than the
        # series for long T, so the tolerance is set by the direct sum's rounding there
        assert got == pytest.approx(direct, rel=1e-9 if T < 100 else 1e-4)


def test_random_walk_matches_the_filter_on_its_increments():
    # W of a random walk is a filter on the white increments: g = cumulative sum of h
    K = 4e-4
    step2 = K * K * DT
    for m in M[:8]:
        g = np.cumsum(_haar(int(m))[::-1])[::-1]
        direct = step2 * float(g @ g)
        assert gmwm.wv_random_walk(np.array([m]), DT, K)[0] == pytest.approx(direct, rel=1e-12)


def test_quantization_matches_the_filter_on_its_draws():
    Q = 2e-3
    for m in M[:8]:
        g = np.convolve(_haar(int(m)), [1.0, -1.0]) * (Q / DT)
        direct = float(g @ g)
        assert gmwm.wv_quantization(np.array([m]), DT, Q)[0] == pytest.approx(direct, rel=1e-12)


def test_drift_is_deterministic_quarter_tau_squared():
    R = 1e-4
    x = R * DT * np.arange(1, 5001)
    wv = haar_wv(x, 1 / DT)
    assert wv.wv == pytest.approx(gmwm.wv_drift(wv.m, DT, R), rel=1e-6)


def test_allan_closed_forms_are_the_large_scale_limit():
    # 2 nu^2 tends to allan.py's continuous closed forms once tau >> dt (relative 1/(2 m^2)
    # for the random walk, O(dt / tau) for the Gauss-Markov term)
    m = 2 ** np.arange(8, 20)
    params = (0.0178, 4.05e-3, 33.9, 4.02e-4)
    two_nu = 2.0 * gmwm.model_wv(("WN", "GM", "RW"), params, m, DT)
    assert two_nu == pytest.approx(composite_avar(m * DT, *params), rel=2e-3)


def test_sum_of_processes_against_monte_carlo():
    # mean WV of 400 records of 2^14 samples of WN + QN + GM + RW against the exact sum; the
    # Monte Carlo mean at each scale has sd (per-record sd) / sqrt(400): 4.5 sd allowed
    # (10 scales tested at once, so a 4.5 sd excursion has probability < 1e-4)
    model = ("WN", "QN", "GM", "RW")
    params = (0.02, 1e-4, 0.01, 0.2, 2e-3)
    rng = np.random.default_rng(7)
    draws = np.array(
        [
            haar_wv(gmwm.simulate(model, params, 1 << 14, 200.0, rng), 200.0, 0.5).wv
            for _ in range(400)
        ]
    )
    m = 2 ** np.arange(draws.shape[1])
    theory = gmwm.model_wv(gmwm.check_model(model), params, m, DT)
    sd_mean = draws.std(axis=0, ddof=1) / math.sqrt(draws.shape[0])
    assert (np.abs(draws.mean(axis=0) - theory) < 4.5 * sd_mean).all()


def test_spectra_integrate_to_the_variance():
    # white sigma^2 = N^2 / dt and stationary Gauss-Markov B^2: the two-sided density over
    # (-1/2, 1/2] cycles per sample integrates to the process variance
    f = (np.arange(400_000) + 0.5) / 400_000 * 0.5
    for model, params, variance in (
        (("WN",), (0.02,), 0.02**2 / DT),
        (("GM",), (3e-3, 0.05), 3e-3**2),
    ):
        s = gmwm.model_spectrum(model, params, DT)(f)
        assert 2.0 * s.mean() * 0.5 == pytest.approx(variance, rel=1e-4)


def test_model_parsing_and_errors():
    assert gmwm.parse_model("wn + 2gm + rw") == ("WN", "GM", "GM", "RW")
    assert gmwm.parse_model("RW+WN") == ("WN", "RW")
    assert gmwm.parameter_names(("WN", "GM", "GM", "RW")) == ["N", "B1", "T1", "B2", "T2", "K"]
    with pytest.raises(gmwm.GMWMError, match="unknown model component 'AR2'"):
        gmwm.parse_model("WN+AR2")
    with pytest.raises(gmwm.GMWMError, match="only GM may repeat"):
        gmwm.check_model(("WN", "WN"))
