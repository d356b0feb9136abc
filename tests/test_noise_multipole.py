"""Several Gauss-Markov terms per axis: profile layout, numpy-only recursion, guarantees kept."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bmg160_emu.noise import NoiseGenerator, ProfileError, load_profile
from bmg160_emu.noise.allan import gauss_markov_avar, overlapping_adev
from bmg160_emu.noise.profile import AxisNoise, Profile
from bmg160_emu.noise.profile_writer import format_profile, write_profile

THREE = AxisNoise(N=0.0, B=0.0, T=0.0, K=0.0, bias=0.0,
                  gm=((2e-3, 5.0), (1.5e-3, 60.0), (1e-3, 900.0)))
MIXED = Profile(
    "mixed",
    AxisNoise(N=0.02, B=0.004, T=30.0, K=4e-4, bias=0.1, gm=((1e-3, 0.5), (2e-3, 300.0))),
    THREE,
    # a term far shorter than a sample (white to double precision) and one of two samples
    AxisNoise(N=0.01, B=0.0, T=0.0, K=0.0, bias=0.0, gm=((1e-2, 1e-5), (3e-3, 0.01))),
)


def chunked(gen, sizes):
    return np.concatenate([gen.generate(k) for k in sizes]) if sizes else np.empty((0, 3))


def test_a_one_term_profile_draws_the_same_process_as_the_sample_by_sample_recursion():
    # the realisation of earlier versions: lfilter over the same normals of the same stream
    from scipy.signal import lfilter

    B, T, rate = 4e-3, 33.9, 200.0
    prof = Profile("gm", *[AxisNoise(N=0.0, B=B, T=T, K=0.0, bias=0.0)] * 3)
    out = NoiseGenerator(prof, rate_hz=rate, seed=3).generate(100_000)
    stream = np.random.SeedSequence(3).spawn(3)[0].spawn(4)[1]  # axis x, stream "gm"
    rng = np.random.Generator(np.random.PCG64(stream))
    x0 = B * rng.standard_normal()
    a = math.exp(-1.0 / (rate * T))
    ref, _ = lfilter([B * math.sqrt(1 - a * a)], [1.0, -a], rng.standard_normal(100_000),
                     zi=[a * x0])
    # rounding only: the two evaluations order the additions differently
    assert np.max(np.abs(out[:, 0] - ref)) < 1e-12 * B


@settings(max_examples=30, deadline=None)
@given(
    plan=st.lists(
        st.tuples(st.integers(0, 40_000), st.sampled_from([100.0, 200.0, 400.0, 1000.0, 2000.0])),
        max_size=6,
    ),
    split=st.integers(1, 9000),
)
def test_several_terms_stay_chunk_invariant_across_rate_changes(plan, split):
    a = NoiseGenerator(MIXED, seed=9)
    b = NoiseGenerator(MIXED, seed=9)
    for count, rate in plan:
        whole = a.generate(count)
        parts = chunked(b, [split] * (count // split) + [count % split])
        assert np.array_equal(parts, whole)
        a.set_rate(rate)
        b.set_rate(rate)


def test_checkpoint_and_restore_replay_several_terms():
    gen = NoiseGenerator(MIXED, seed=4)
    gen.generate(777)
    saved = gen.checkpoint()
    first = gen.generate(50_000)
    gen.set_rate(1000.0)
    after = gen.generate(3000)
    gen.restore(saved)
    np.testing.assert_array_equal(gen.generate(50_000), first)
    gen.set_rate(1000.0)
    np.testing.assert_array_equal(gen.generate(3000), after)


def test_the_terms_add_up_to_the_closed_form_allan_deviation():
    # 10 h at 100 Hz of three terms only; each octave ADEV point below L/10 has >= 20 edf,
    # i.e. a 1-sigma error <= 16 % in ADEV; 25 % is ~1.6 sigma at the worst (longest) tau,
    # checked over 13 points, and the variance of the sum is checked to 10 % (the 900 s
    # term alone gives ~40 independent values in 10 h: 1-sigma 22 % on its variance, 1e-3^2
    # of the total 7.25e-6: the sum's 1-sigma is ~4 %)
    prof = Profile("three", THREE, THREE, THREE)
    x = NoiseGenerator(prof, rate_hz=100.0, seed=21).generate(10 * 3600 * 100)[:, 1]
    total = sum(B * B for B, _ in THREE.gm)
    assert x.var() == pytest.approx(total, rel=0.10)
    curve = overlapping_adev(x, 100.0)
    sel = (curve.taus >= 0.1) & (curve.taus <= 3600.0)
    model = np.sqrt(sum(gauss_markov_avar(B, T, curve.taus[sel]) for B, T in THREE.gm))
    assert np.all(np.abs(curve.adev[sel] / model - 1) < 0.25)


def test_a_term_shorter_than_a_sample_is_white_noise_of_std_b():
    x = NoiseGenerator(MIXED, rate_hz=200.0, seed=5).generate(200_000)[:, 2]
    # z: white N = 0.01 (std 0.141 at 200 Hz), T = 1e-5 s term of std 0.01, T = 0.01 s term
    # of std 3e-3: variance 0.02 + 1e-4 + 9e-6; 2e5 samples estimate it to 0.3 % (1 sigma)
    assert x.var() == pytest.approx(0.01**2 * 200 + 1e-4 + 9e-6, rel=0.015)


def test_the_generator_path_imports_no_scipy():
    code = (
        "import sys\n"
        "from bmg160_emu.noise import NoiseGenerator\n"
        "from bmg160_emu.noise.profile import AxisNoise, Profile\n"
        "a = AxisNoise(N=0.02, B=0.004, T=30.0, K=4e-4, bias=0.0, gm=((1e-3, 5.0),))\n"
        "g = NoiseGenerator(Profile('p', a, a, a), seed=1)\n"
        "g.generate(100_000); g.set_rate(2000.0); g.generate(10)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_gm_list_round_trips_through_toml_and_b_t_may_be_left_out(tmp_path):
    path = tmp_path / "multi.toml"
    write_profile(MIXED, path)
    text = path.read_text()
    assert "gm = [" in text and "{ B = 0.002, T = 5.0 }" in text
    back = load_profile(path)
    assert back == MIXED
    assert back.y.B == 0.0 and back.y.gauss_markov_terms == THREE.gm
    assert back.x.gauss_markov_terms[0] == (0.004, 30.0)
    assert format_profile(back) == text


@pytest.mark.parametrize(
    ("gm", "message"),
    [
        ("1.0", "gm must be a list"),
        ("[{ B = 0.001 }]", r"gm\[0\]: needs exactly B"),
        ("[{ B = 0.001, T = 0.0 }]", r"gm\[0\]: T must be positive"),
        ("[{ B = -0.001, T = 5.0 }]", r"gm\[0\]: B must not be negative"),
        ("[{ B = 0.001, T = 5.0, C = 1.0 }]", "needs exactly B"),
        ("[3.0]", r"a term is \{ B = \.\.\., T = \.\.\. \}"),
    ],
)
def test_bad_gm_entries_are_named(tmp_path, gm, message):
    axis = f"N = 0.02\nK = 0.0\nbias = 0.0\ngm = {gm}\n"
    path = tmp_path / "bad.toml"
    path.write_text(f"[x]\n{axis}[y]\n{axis}[z]\n{axis}")
    with pytest.raises(ProfileError, match=message):
        load_profile(path)


def test_paper_mode_takes_the_variance_of_every_term():
    paper = load_profile("paper").x
    extra = AxisNoise(**{**paper.__dict__, "gm": ((1e-3, 5.0),)})
    from bmg160_emu.noise.discretization import axis_coefficients, paper_sigma_N

    c = axis_coefficients(extra, 200.0, "paper")
    b_total = math.sqrt(paper.B**2 + 1e-6)
    assert c.white_std == paper_sigma_N(paper.sigma_gyro, b_total, paper.K, 0.005, paper.sigma_K)
    assert len(c.poles) == 2


def test_the_random_walk_is_the_cumulative_sum_of_its_stream_to_rounding():
    K, rate = 4e-4, 200.0
    prof = Profile("rw", *[AxisNoise(N=0.0, B=0.0, T=0.0, K=K, bias=0.0)] * 3)
    out = NoiseGenerator(prof, rate_hz=rate, seed=5).generate(100_000)
    stream = np.random.SeedSequence(5).spawn(3)[2].spawn(4)[2]  # axis z, stream "rw"
    rng = np.random.Generator(np.random.PCG64(stream))
    ref = np.cumsum(rng.standard_normal(100_000) * K * math.sqrt(1 / rate))
    # the walk reaches ~K sqrt(500 s) = 0.009 deg/s; the summation orders differ by rounding
    assert np.max(np.abs(out[:, 2] - ref)) < 1e-13
