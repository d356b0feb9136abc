"""Allan-variance building blocks: closed forms, confidence bounds, IEEE read-offs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bmg160_emu.noise.allan import (
    FLICKER_ADEV_FACTOR,
    composite_avar,
    gauss_markov_avar,
    gauss_markov_avar_unit,
    overlapping_adev,
)
from bmg160_emu.noise.readoffs import ieee_readoffs


def test_flicker_factor_is_sqrt_2ln2_over_pi():
    assert FLICKER_ADEV_FACTOR == pytest.approx(0.6643, abs=1e-4)  # IEEE 952: B = min / 0.664


def test_gauss_markov_avar_limits():
    T = 33.9
    tau = np.array([1e-6, 1e-3 * T, 1e-3 * T * 1.0001, 1e4 * T])
    g = gauss_markov_avar_unit(tau, T)
    # tau << T: looks like a random walk with K^2 = 2 q^2 / T  ->  2 tau / (3 T)
    assert g[0] == pytest.approx(2 * tau[0] / (3 * T), rel=1e-6)
    # the series and the closed form agree where they meet
    assert g[1] == pytest.approx(g[2], rel=1e-3)
    # tau >> T: white-like, 2 T / tau
    assert g[3] == pytest.approx(2 * T / tau[3], rel=1e-3)


def test_gauss_markov_avar_peak_sits_near_two_t():
    # the closed form's maximum over tau is at tau ~ 1.89 T (value 0.4 q^2 within a few %)
    tau = np.geomspace(0.1, 100, 4000)
    g = gauss_markov_avar(1.0, 1.0, tau)
    assert tau[np.argmax(g)] == pytest.approx(1.89, rel=0.02)


def test_white_noise_adev_is_n_over_sqrt_tau_inside_its_confidence_band():
    rng = np.random.default_rng(1)
    rate, N = 200.0, 0.02
    x = rng.standard_normal(200_000) * N * math.sqrt(rate)
    curve = overlapping_adev(x, rate)
    expected = np.sqrt(composite_avar(curve.taus, N, 0.0, 0.0, 0.0))
    inside = (curve.ci_low <= expected) & (expected <= curve.ci_high)
    # 68.3 % bands on ~16 points: about 11 inside; fewer than 7 would be a > 3 sigma event
    assert inside.sum() >= 7
    assert np.all(curve.ci_low < curve.adev) and np.all(curve.adev < curve.ci_high)


def test_readoffs_find_the_slope_lines_of_a_synthetic_curve():
    from bmg160_emu.noise.allan import AllanCurve

    N, K = 0.02, 4e-4
    taus = 0.005 * 2.0 ** np.arange(22)
    adev = np.sqrt(N**2 / taus + K**2 * taus / 3)
    ones = np.ones_like(taus)
    curve = AllanCurve(taus, adev, ones, ones * 100, adev * 0.9, adev * 1.1, 0.683)
    ro = ieee_readoffs(curve)
    assert ro["N_at_tau_1s"]["value"] == pytest.approx(N, rel=0.01)
    assert ro["K_at_tau_3s"]["value"] == pytest.approx(K, rel=0.05)
    assert ro["B_flicker"]["value"] == pytest.approx(adev.min() / FLICKER_ADEV_FACTOR)


# 16383 / 16385: just below and above the first long octave (4 x allan._SHORT_M);
# 139_265: three chunks of the short pass, the last shorter than its halo
@pytest.mark.parametrize("n", [1000, 4097, 16_383, 16_385, 123_457, 139_265])
def test_the_numpy_octave_oadev_agrees_with_allantools(n):
    import allantools

    from bmg160_emu.noise.allan import octave_oadev

    # a biased 3-axis record, read as a strided column (the identify path): the same taus,
    # counts and deviations to rounding of the final sums
    data = np.random.default_rng(n).standard_normal((n, 3)) * 0.25 + 0.1
    data[:, 1] += np.cumsum(np.random.default_rng(1).standard_normal(n)) * 1e-3
    taus, adev, _err, counts = allantools.oadev(
        np.ascontiguousarray(data[:, 1]), rate=200.0, data_type="freq", taus="octave")
    mine_taus, mine_adev, mine_counts = octave_oadev(data[:, 1], 200.0)
    np.testing.assert_array_equal(mine_taus, taus)
    np.testing.assert_array_equal(mine_counts, counts)
    np.testing.assert_allclose(mine_adev, adev, rtol=1e-12, atol=0)



def test_a_float32_record_gets_the_deviations_of_its_double_precision_copy():
    """A record stored as float32 (a logger's usual type) is summed in double precision:
    the deviations are allantools' on the record widened to float64, not float32 sums
    (which were 6e-8 off on 70,000 samples)."""
    import allantools

    from bmg160_emu.noise.allan import octave_oadev

    data = (np.random.default_rng(3).standard_normal(70_000) * 0.25 + 0.1).astype(np.float32)
    _taus, adev, _err, _counts = allantools.oadev(
        data.astype(float), rate=100.0, data_type="freq", taus="octave")
    np.testing.assert_allclose(octave_oadev(data, 100.0)[1], adev, rtol=1e-12, atol=0)

def test_the_spectra_thread_gives_the_numbers_of_one_thread(monkeypatch):
    """identify_axis computes a long record's PSDs on a second thread beside its Allan
    deviation: the identification is the same, number for number, as on one thread."""
    import threading

    from scipy import signal

    from bmg160_emu.noise import NoiseGenerator
    from bmg160_emu.noise import identify as identify_module

    # 2^20 samples: the threshold, so the default takes the thread; a filtered, quantized
    # record so that the stage search (the second PSD) runs too
    rate = 200.0
    n = identify_module.SPECTRA_THREAD_SAMPLES
    raw = NoiseGenerator("paper", rate_hz=rate, seed=5).generate(n)[:, 0]
    x = np.round(signal.lfilter(*signal.butter(2, 40.0, fs=rate), raw) / 0.01) * 0.01
    threads_seen: dict[str, set[str]] = {}
    psd = identify_module.one_sided_psd

    def seen(*args, **kwargs):
        names = threads_seen.setdefault(run, set())
        names.add(threading.current_thread().name.rsplit("_", 1)[0])
        return psd(*args, **kwargs)

    monkeypatch.setattr(identify_module, "one_sided_psd", seen)
    # a second CPU whatever this host's affinity gives (a one-CPU runner would take the
    # single-thread route both times)
    monkeypatch.setattr("bmg160_emu.noise.worker_thread.usable_cpus", lambda: 2)
    run = "threaded"
    threaded = identify_module.identify_axis(x, rate)
    monkeypatch.setattr(identify_module, "SPECTRA_THREAD_SAMPLES", n + 1)
    run = "single"
    single = identify_module.identify_axis(x, rate)
    assert threaded.stage is not None  # the stage's own PSD was read
    for field in ("mean", "std", "psd_white_N", "tau_range_reason", "notes"):
        assert getattr(threaded, field) == getattr(single, field)
    np.testing.assert_array_equal(threaded.spectrum.psd, single.spectrum.psd)
    assert repr(threaded.fit) == repr(single.fit)
    assert threads_seen == {"threaded": {"bmg160-spectra"}, "single": {"MainThread"}}
