"""Theoretical Haar wavelet variance of each process, against exact sums and Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bmg160_emu.noise import gmwm, gmwm_processes
from bmg160_emu.noise.allan import composite_avar
from bmg160_emu.noise.wavelet import dyadic_scales, haar_wv, wv_covariance_finite

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


# -- the exact finite-record covariance of the estimates (Omega) -----------------------------


def _covariance_of_record(model, params, n: int) -> np.ndarray:
    """Covariance matrix of n samples of the model as simulate() draws them."""
    idx = np.arange(n)
    lag = np.abs(idx[:, None] - idx[None, :])
    S = np.zeros((n, n))
    for comp, p in zip(model, gmwm_processes._split(model, params)):
        if comp == "WN":
            S += np.eye(n) * p[0] ** 2 / DT
        elif comp == "QN":
            S += (p[0] / DT) ** 2 * (2.0 * (lag == 0) - (lag == 1))
        elif comp == "GM":
            S += p[0] ** 2 * np.exp(-DT / p[1] * lag)
        elif comp == "RW":  # the sum of k + 1 steps
            S += p[0] ** 2 * DT * (np.minimum(idx[:, None], idx[None, :]) + 1.0)
    return S


def _exact_wv_covariance(model, params, n: int, ms) -> np.ndarray:
    """cov(nu_i, nu_j) = 2 tr(A_i S A_j S), nu_i = x' A_i x the estimate as a quadratic form."""
    S = _covariance_of_record(model, params, n)
    AS = []
    for m in ms:
        count = n - 2 * m + 1
        H = np.zeros((count, n))
        for r, t in enumerate(range(2 * m - 1, n)):
            H[r, t - m + 1 : t + 1] = 1.0 / (2 * m)
            H[r, t - 2 * m + 1 : t - m + 1] = -1.0 / (2 * m)
        AS.append(H.T @ H @ S / count)
    return np.array([[2.0 * np.einsum("ij,ji->", a, b) for b in AS] for a in AS])


@pytest.mark.parametrize(
    ("model", "params", "n"),
    [
        (("WN",), (0.02,), 64),
        (("RW",), (4e-4,), 64),
        (("WN", "QN"), (0.02, 1e-3), 64),
        (("WN", "GM", "RW"), (0.02, 4e-3, 0.2, 4e-3), 64),
        # long enough for the quadrature between the breaks (gaps of >= 64 lags)
        (("WN", "GM", "RW"), (0.02, 4e-3, 2.0, 4e-3), 1500),
        (("WN", "GM", "GM", "RW"), (0.02, 4e-3, 0.05, 4e-3, 1.0, 4e-3), 1500),
    ],
)
def test_finite_covariance_is_the_quadratic_forms_covariance(model, params, n):
    # every dyadic scale up to n / 2, the top one with M << 2m coefficients; with n = 64 every
    # lag is summed term by term (agreement to rounding), with n = 1500 the Gauss-Legendre
    # pieces between the breaks carry the sum (measured 4e-5 relative to the diagonal)
    ms = dyadic_scales(n)
    P, decay = gmwm_processes.model_second_sum(model, params, DT)
    got = wv_covariance_finite(ms, n, P, decay)
    want = _exact_wv_covariance(model, params, n, ms)
    scale = np.sqrt(np.outer(np.diag(want), np.diag(want)))
    assert np.max(np.abs(got - want) / scale) < (1e-10 if n < 100 else 1e-3)


def test_finite_covariance_matches_monte_carlo_at_the_top_scale():
    # 2000 random walks of 4096 samples, every scale to m = 2048 (M = 1): the relative sd of
    # a Monte Carlo variance is about sqrt(2 / 2000) (1 + kurtosis share) < 10 % at the top,
    # bound 20 %; the correlation of the two top scales has Monte Carlo sd below 0.03, bound
    # 0.08 (the asymptotic form is 0.085 off there already at M = n / 2)
    rng = np.random.default_rng(12)
    n, reps = 4096, 2000
    draws = np.array([haar_wv(np.cumsum(rng.standard_normal(n)), 1.0).wv for _ in range(reps)])
    mc = np.cov(draws.T)
    ms = dyadic_scales(n)
    P, decay = gmwm_processes.model_second_sum(("RW",), (1.0,), 1.0)
    omega = wv_covariance_finite(ms, n, P, decay)
    assert np.diag(omega) == pytest.approx(np.diag(mc), rel=0.2)
    corr = omega[-2, -1] / math.sqrt(omega[-2, -2] * omega[-1, -1])
    corr_mc = mc[-2, -1] / math.sqrt(mc[-2, -2] * mc[-1, -1])
    assert abs(corr - corr_mc) < 0.08
