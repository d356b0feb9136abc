"""Periodic terms from an Allan deviation curve alone (issue 37), and the model-order note
when --poles asks for more terms than AICc prefers."""

import numpy as np
import pytest

from bmg160_emu.noise import NoiseGenerator
from bmg160_emu.noise.allan import overlapping_adev
from bmg160_emu.noise.identify import identify, identify_curve
from bmg160_emu.noise.output_stage import sine_avar_unit
from bmg160_emu.noise.profile import AxisNoise, Profile


@pytest.fixture(scope="module")
def line_curve():
    # white noise and a 0.05 deg/s line at 2 Hz, 20 min at 100 Hz: the line's shoulder rises
    # 60 % above the white line at tau = 0.2 s
    axis = AxisNoise(N=0.01, B=0.0, T=0.0, K=0.0, bias=0.0, sine=((0.05, 2.0),))
    x = NoiseGenerator(Profile("l", axis, axis, axis), rate_hz=100.0, seed=9).generate(
        120_000)[:, 0]
    return overlapping_adev(x, 100.0), x.size


def test_a_line_comes_back_from_the_curve_alone(line_curve):
    curve, n = line_curve
    found = identify_curve(curve.taus, curve.adev, 100.0, n)
    assert len(found.sines) == 1
    amplitude, frequency = found.sines[0]
    # the amplitude's interval from the fit; 20 min: A to a few %, f to 1 %
    assert amplitude.ci_low <= 0.05 <= amplitude.ci_high
    assert frequency == pytest.approx(2.0, rel=0.01)
    assert found.chi2_reduced < 3.0
    assert any("periodic term on the curve" in note for note in found.notes)
    assert found.to_axis_noise().sine[0][1] == frequency
    without = identify_curve(curve.taus, curve.adev, 100.0, n, periodic=False)
    assert without.chi2_reduced > 10 * found.chi2_reduced  # the shoulder unexplained


def test_white_noise_gets_no_line(line_curve):
    x = NoiseGenerator("paper", rate_hz=100.0, seed=4).generate(120_000)[:, 0]
    curve = overlapping_adev(x, 100.0)
    assert identify_curve(curve.taus, curve.adev, 100.0, x.size).sines == []


def test_sampled_sine_allan_variance_tends_to_the_continuous_one():
    taus = np.array([0.01, 0.02, 0.04, 1.0, 10.0])
    sampled = sine_avar_unit(taus, 0.5, 100.0)
    assert np.allclose(sampled, sine_avar_unit(taus, 0.5), rtol=1e-3)
    # near the Nyquist frequency the samples' ripple: at m = 1 a line at 49 Hz keeps its
    # whole variance A^2 sin^4 / sin^2 = A^2 sin^2(pi 0.49) ~ A^2 where the continuous
    # formula gives a fraction of it
    near = sine_avar_unit(np.array([0.01]), 49.0, 100.0)[0]
    assert near == pytest.approx(np.sin(np.pi * 0.49) ** 2, rel=1e-9)


def test_poles_asking_for_more_says_what_aicc_prefers_and_what_was_kept():
    x = NoiseGenerator("paper", rate_hz=200.0, seed=5).generate(200 * 1800)[:, 0]
    axis = identify(x, 200.0, poles=3).axes[0]
    note = next(n for n in axis.notes if "asked for (--poles)" in n)
    assert "AICc prefers" in note and f"kept: {len(axis.terms)} term" in note
    assert "-" not in note.split("prefers")[1].split("(")[0]  # a positive difference
