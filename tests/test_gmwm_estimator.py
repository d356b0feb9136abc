"""The GMWM estimator: round trip on the paper profile, consistency, coverage, selection."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bmg160_emu.noise import NoiseGenerator, gmwm, load_profile
from bmg160_emu.noise.wavelet import haar_wv

PAPER = load_profile("paper").x
HOUR = 3600
RATE = 200.0


@pytest.mark.slow
def test_paper_profile_round_trips_within_todays_tolerances():
    # the Allan round trip's record and bounds (tests/test_identify_roundtrip.py): seed 2,
    # 6 h at 200 Hz, physical mode; N 3 %, B 30 %, T a factor 2.5, K 35 %
    x = NoiseGenerator("paper", rate_hz=RATE, seed=2).generate(6 * HOUR * 200)[:, 0]
    fit = gmwm.identify_gmwm(x, RATE)
    assert fit.value("N") == pytest.approx(PAPER.N, rel=0.03)
    assert fit.value("B") == pytest.approx(PAPER.B, rel=0.30)
    assert 1 / 2.5 < fit.value("T") / PAPER.T < 2.5
    assert fit.value("K") == pytest.approx(PAPER.K, rel=0.35)
    for name in ("N", "B", "T", "K"):  # and each interval holds its truth on this record
        e = fit.estimates[name]
        assert e.ci_low <= getattr(PAPER, name) <= e.ci_high, name
    # the J test does not reject the generator's own model (p = 0.68 on this record)
    assert fit.p_value > 0.01


MODEL = ("WN", "GM")
TRUTH = (0.02, 0.01, 0.5)  # N deg/s/sqrt(Hz), B deg/s, T s: a pole well inside the record


def _fit(n: int, seed: int, model=MODEL, truth=TRUTH) -> gmwm.GMWMFit:
    rng = np.random.default_rng(seed)
    return gmwm.identify_gmwm(gmwm.simulate(model, truth, n, RATE, rng), RATE, model)


def test_estimates_converge_at_the_root_n_rate():
    # one seed, 2^15 then 2^19 samples (16 times longer): the asymptotic sd of each log
    # parameter at the truth shrinks by sqrt(16) = 4 (Omega ~ 1 / M), and the long record's
    # estimates sit within 3.3 sd (99.9 %) of the truth
    sds = []
    for n in (1 << 15, 1 << 19):
        wv = haar_wv(gmwm.simulate(MODEL, TRUTH, n, RATE, np.random.default_rng(21)), RATE, 0.5)
        omega = gmwm.omega_of(MODEL, TRUTH, wv)
        sds.append(np.sqrt(np.diag(gmwm._log_covariance(MODEL, np.log(TRUTH), wv, omega))))
        fit = gmwm.gmwm_fit(wv, MODEL)
    assert np.allclose(sds[0] / sds[1], 4.0, rtol=0.05), sds[0] / sds[1]
    z = (np.log(fit.params) - np.log(TRUTH)) / np.sqrt(np.diag(fit.log_cov))
    assert (np.abs(z) < 3.3).all(), z


@pytest.mark.slow
def test_asymptotic_intervals_cover_95_percent():
    # 200 records of 2^17 samples (655 s, 1300 T) of a clearly visible pole (its Allan peak,
    # 0.38 B^2 at tau = 2 T, is 2.4 times the white level there): coverage of each 95 %
    # interval is binomial with sd sqrt(0.95 * 0.05 / 200) = 1.5 points; 3 sd either side
    # gives 90.4 .. 99.6. (A weak pole, B = 0.01, covers 84-90 % at this length: the
    # estimator is not yet normal there; docs/gmwm.md.)
    truth = (0.02, 0.05, 0.5)
    hits = np.zeros(3)
    seeds = range(1000, 1200)
    for seed in seeds:
        fit = _fit(1 << 17, seed, MODEL, truth)
        for k, name in enumerate(("N", "B", "T")):
            e = fit.estimates[name]
            hits[k] += e.ci_low <= truth[k] <= e.ci_high
    coverage = hits / len(seeds)
    assert ((coverage >= 0.904) & (coverage <= 0.996)).all(), coverage


@pytest.mark.slow
def test_parametric_bootstrap_intervals_cover_95_percent():
    # 40 records of white noise + random walk (crossing at tau = sqrt(3) N / K = 3.5 s, the
    # record is 82 s), 60 bootstrap replicates each: coverage has sd sqrt(0.95 * 0.05 / 40) =
    # 3.4 points; a 60-replicate percentile interval adds its own spread, so the bound is
    # 3 sd below and nothing above: >= 85 %
    model, truth = ("WN", "RW"), (0.02, 1e-2)
    hits = np.zeros(2)
    for seed in range(40):
        fit = gmwm.bootstrap(_fit(1 << 14, 3000 + seed, model, truth), replicates=60, seed=seed)
        for k, name in enumerate(("N", "K")):
            e = fit.estimates[name]
            assert e.boot_low is not None and e.boot_high is not None
            hits[k] += e.boot_low <= truth[k] <= e.boot_high
    assert (hits / 40 >= 0.85).all(), hits


def test_bootstrap_writes_its_intervals_beside_the_asymptotic_ones():
    fit = gmwm.bootstrap(_fit(1 << 14, 5, ("WN", "RW"), (0.02, 1e-3)), replicates=20, seed=1)
    e = fit.estimates["N"]
    assert e.boot_low is not None and e.boot_high is not None and e.boot_low < e.value < e.boot_high
    assert fit.bootstrap_samples is not None and fit.bootstrap_samples.shape == (20, 2)
    d = fit.as_dict()
    assert d["parameters"]["N"]["ci95_bootstrap"] == [e.boot_low, e.boot_high]
    json.dumps(d)


def _record(model, truth, n, seed):
    return haar_wv(gmwm.simulate(model, truth, n, RATE, np.random.default_rng(seed)), RATE, 0.5)


def test_selection_prefers_no_pole_when_there_is_none():
    # white + random walk only: the Gauss-Markov pole buys nothing and pays 2 p
    wv = _record(("WN", "RW"), (0.02, 1e-3), 1 << 18, 31)
    sel = gmwm.select_model(wv, [("WN", "RW"), ("WN", "GM", "RW"), ("WN", "GM")])
    assert sel.best.model == ("WN", "RW"), sel.table()


def test_selection_finds_the_pole_of_the_generators_model():
    truth = (0.02, 0.01, 1.0, 1e-3)
    wv = _record(("WN", "GM", "RW"), truth, 1 << 18, 32)
    sel = gmwm.select_model(wv, [("WN", "RW"), ("WN", "GM"), ("WN", "GM", "RW")])
    assert sel.best.model == ("WN", "GM", "RW"), sel.table()


def test_selection_finds_two_poles_and_orders_them():
    truth = (0.02, 0.01, 0.1, 0.01, 5.0)
    wv = _record(("WN", "GM", "GM"), truth, 1 << 18, 33)
    sel = gmwm.select_model(wv, [("WN", "GM"), ("WN", "GM", "GM"), ("WN", "GM", "RW")])
    best = sel.best
    assert best.model == ("WN", "GM", "GM"), sel.table()
    # every parameter within its 99.9 % interval (3.3 sd; five at once: all hold with
    # probability > 0.995 if the intervals are right)
    z = (np.log(best.params) - np.log(truth)) / np.sqrt(np.diag(best.log_cov))
    assert (np.abs(z) < 3.3).all(), dict(zip(best.names, z))


def test_a_record_too_short_for_the_model_is_refused():
    wv = haar_wv(np.random.default_rng(1).standard_normal(16), RATE, 0.5)  # 3 scales
    with pytest.raises(gmwm.GMWMError, match="too short for this model"):
        gmwm.gmwm_fit(wv, ("WN", "GM", "RW"))


def test_fit_reports_json_ready_results():
    fit = _fit(1 << 15, 3)
    d = fit.as_dict()
    assert d["model"] == "WN+GM" and set(d["parameters"]) == {"N", "B", "T"}
    assert d["parameters"]["T"]["unit"] == "s" and d["dof"] == fit.wv.m.size - 3
    assert math.isfinite(d["wic"]) and 0.0 <= d["p_value"] <= 1.0
    # the fitted curve passes within 4 sd (Omega's diagonal) of every estimated point
    z = (fit.wv.wv - fit.fitted_wv()) / np.sqrt(np.diag(fit.omega))
    assert (np.abs(z) < 4.0).all(), z
    json.dumps(d)
