"""The noise generator: seeded, per-axis, chunk invariant, rate changes, clear errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bmg160_emu.noise import NoiseGenerator, load_profile
from bmg160_emu.noise.profile import AxisNoise, Profile

WITH_Q_AND_R = Profile(
    "qr",
    AxisNoise(N=0.02, B=0.004, T=30.0, K=4e-4, bias=0.1, Q=1e-3, R=1e-4),
    AxisNoise(N=0.01, B=0.0, T=0.0, K=0.0, bias=0.0),
    AxisNoise(N=0.0, B=0.004, T=5.0, K=4e-4, bias=-0.2, Q=2e-3),
)


def chunked(gen: NoiseGenerator, sizes: list[int]) -> np.ndarray:
    return np.concatenate([gen.generate(k) for k in sizes]) if sizes else np.empty((0, 3))


def test_output_is_n_by_3_float64_with_the_bias():
    out = NoiseGenerator("paper", seed=1).generate(200 * 60)
    assert out.shape == (12000, 3) and out.dtype == np.float64
    # mean of 1 min: white error 0.25/sqrt(12000) = 0.0023 deg/s, Gauss-Markov error up to
    # about B = 0.004 deg/s; 0.02 is > 4 sigma.
    assert np.all(np.abs(out.mean(axis=0) - 0.116359) < 0.02)


def test_same_seed_same_stream_other_seed_other_stream():
    a = NoiseGenerator(seed=5).generate(1000)
    assert np.array_equal(a, NoiseGenerator(seed=5).generate(1000))
    assert not np.array_equal(a, NoiseGenerator(seed=6).generate(1000))


def test_axes_are_independent_streams():
    out = NoiseGenerator(seed=5).generate(100_000)
    corr = np.corrcoef(out.T)
    # correlation of 1e5 independent samples scatters by 1/sqrt(1e5) = 0.003; 0.02 is ~6 sigma
    assert np.all(np.abs(corr[np.triu_indices(3, 1)]) < 0.02)


@settings(max_examples=40, deadline=None)
@given(
    sizes=st.lists(st.integers(min_value=0, max_value=3000), max_size=25),
    profile=st.sampled_from(["paper", "datasheet", "qr"]),
    mode=st.sampled_from(["physical", "paper"]),
)
def test_any_chunking_gives_the_same_samples(sizes, profile, mode):
    prof = WITH_Q_AND_R if profile == "qr" else load_profile(profile)
    if mode == "paper" and profile != "paper":
        mode = "physical"
    total = sum(sizes)
    whole = NoiseGenerator(prof, seed=11, mode=mode).generate(total)
    assert np.array_equal(chunked(NoiseGenerator(prof, seed=11, mode=mode), sizes), whole)


@pytest.mark.slow
def test_one_call_of_a_million_equals_a_million_calls_of_one():
    n = 1_000_000
    whole = NoiseGenerator("paper", seed=3).generate(n)
    gen = NoiseGenerator("paper", seed=3)
    one_by_one = np.empty((n, 3))
    for k in range(n):
        one_by_one[k] = gen.generate(1)[0]
    assert np.array_equal(one_by_one, whole)


@settings(max_examples=30, deadline=None)
@given(
    plan=st.lists(
        st.tuples(st.integers(0, 2500), st.sampled_from([100.0, 200.0, 400.0, 1000.0, 2000.0])),
        max_size=8,
    ),
    split=st.integers(1, 700),
)
def test_rate_changes_are_chunk_invariant(plan, split):
    # the same schedule of (samples, then new rate) cut into calls of `split` samples
    a = NoiseGenerator(WITH_Q_AND_R, seed=9)
    b = NoiseGenerator(WITH_Q_AND_R, seed=9)
    for count, rate in plan:
        whole = a.generate(count)
        parts = chunked(b, [split] * (count // split) + [count % split])
        assert np.array_equal(parts, whole)
        a.set_rate(rate)
        b.set_rate(rate)


def test_set_rate_carries_the_random_walk_and_rescales_the_white_term():
    profile = Profile(
        "rw-only",
        *[AxisNoise(N=0.0, B=0.0, T=0.0, K=1.0, bias=0.0)] * 2,
        AxisNoise(N=0.02, B=0.0, T=0.0, K=0.0, bias=0.0),
    )
    gen = NoiseGenerator(profile, rate_hz=200.0, seed=4)
    before = gen.generate(10_000)
    gen.set_rate(2000.0)
    after = gen.generate(10_000)
    # random walk: the first step at 2000 Hz is K sqrt(1/2000) = 0.022 deg/s at one sigma,
    # while the walk has wandered ~ K sqrt(50 s) = 7 deg/s: continuity shows within 0.2
    assert abs(after[0, 0] - before[-1, 0]) < 0.2
    # white std N sqrt(fs): 0.283 deg/s at 200 Hz, 0.894 deg/s at 2000 Hz;
    # 10,000 samples estimate a std within 0.7 % (1 sigma), 5 % is > 7 sigma
    assert before[:, 2].std() == pytest.approx(0.02 * np.sqrt(200), rel=0.05)
    assert after[:, 2].std() == pytest.approx(0.02 * np.sqrt(2000), rel=0.05)
    assert gen.rate_hz == 2000.0


def test_set_rate_mid_buffer_equals_set_rate_on_a_fresh_stream():
    a = NoiseGenerator("paper", seed=8)
    a.generate(3)  # leaves computed samples waiting in the small-request buffer
    a.set_rate(400.0)
    b = NoiseGenerator("paper", seed=8)
    b.generate(3)
    b.set_rate(400.0)
    assert np.array_equal(a.generate(5000), chunked(b, [1] * 100 + [4900]))


@pytest.mark.parametrize("rate", [0, 150.0, 3000, "fast", None])
def test_unsupported_rate_is_a_clear_value_error(rate):
    with pytest.raises(ValueError, match="output data rate"):
        NoiseGenerator(rate_hz=rate)
    gen = NoiseGenerator()
    with pytest.raises(ValueError, match="output data rate"):
        gen.set_rate(rate)


def test_unknown_mode_is_a_clear_value_error():
    with pytest.raises(ValueError, match="unknown noise mode"):
        NoiseGenerator(mode="exact")


@pytest.mark.parametrize("n", [-1, 2.5, "3"])
def test_bad_sample_count_is_rejected(n):
    with pytest.raises((TypeError, ValueError), match="number of samples"):
        NoiseGenerator().generate(n)


def test_zero_samples_is_an_empty_block():
    assert NoiseGenerator().generate(0).shape == (0, 3)


def test_rate_ramp_adds_r_times_t():
    profile = Profile("ramp", *[AxisNoise(N=0.0, B=0.0, T=0.0, K=0.0, bias=1.0, R=0.5)] * 3)
    gen = NoiseGenerator(profile, rate_hz=100.0, seed=0)
    first = gen.generate(100)
    gen.set_rate(1000.0)
    second = gen.generate(1000)
    # sample k at t = (k + 1) dt: 1 s after 100 samples at 100 Hz, then 1 s more at 1000 Hz
    assert first[-1, 0] == pytest.approx(1.0 + 0.5 * 1.0)
    assert second[-1, 0] == pytest.approx(1.0 + 0.5 * 2.0)


def test_restoring_a_checkpoint_replays_the_stream_and_a_later_rate_change():
    gen = NoiseGenerator("paper", rate_hz=200.0, seed=11)
    gen.generate(10)
    saved = gen.checkpoint()
    first = gen.generate(3000)
    gen.set_rate(400.0)
    after = gen.generate(500)
    gen.restore(saved)
    np.testing.assert_array_equal(gen.generate(3000), first)
    gen.set_rate(400.0)
    np.testing.assert_array_equal(gen.generate(500), after)
