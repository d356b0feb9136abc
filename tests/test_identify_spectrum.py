"""One-sided Welch PSD: scipy's estimate, and the stated convention (white reads 2 N^2)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import welch

from bmg160_emu.noise.spectrum import (
    gauss_markov_psd,
    one_sided_psd,
    white_density_from_psd,
    white_level_band,
)


@pytest.mark.parametrize(("n", "segment"), [(1001, 256), (70_000, 4096), (70_001, 4097)])
def test_psd_is_scipys_welch_of_the_mean_removed_record(n, segment):
    x = np.random.default_rng(n).standard_normal(n) + 3.0
    ours = one_sided_psd(x, 200.0, segment)
    f, p = welch(x - x.mean(), fs=200.0, nperseg=segment, detrend=False)
    np.testing.assert_allclose(ours.frequency_hz, f[1:])
    np.testing.assert_allclose(ours.psd, p[1:], rtol=1e-10)


def test_white_noise_reads_two_n_squared_one_sided():
    rate, N = 200.0, 0.0178
    x = np.random.default_rng(1).standard_normal(400_000) * N * math.sqrt(rate)
    spectrum = one_sided_psd(x, rate, 4096)
    # ~95 segments x 800 bins averaged in the band: the level is known to well under 1 %
    sel = (spectrum.frequency_hz > 4) & (spectrum.frequency_hz < 20)
    assert spectrum.psd[sel].mean() == pytest.approx(2 * N**2, rel=0.02)
    assert white_density_from_psd(spectrum, white_level_band(rate)) == pytest.approx(N, rel=0.01)


def test_gauss_markov_psd_integrates_to_its_variance():
    B, T = 0.004, 33.9
    f = np.geomspace(1e-7, 1e3, 200_001)
    trapezoid = getattr(np, "trapezoid", None) or np.trapz  # numpy < 2 has only trapz
    integral = trapezoid(gauss_markov_psd(B, T, f), f)
    assert integral == pytest.approx(B**2, rel=1e-3)  # one-sided PSD integrates to variance
