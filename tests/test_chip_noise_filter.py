"""The chip's noise goes through its own low-pass (issue 23): at rest, the RATE registers'
standard deviation and sample correlation follow the BW register, for every code and part,
as the profile through that code's filter predicts; N, B, T, K read from a long register
recording are the profile's; the data_high_bw path and the paper mode are unfiltered."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bmg160_emu.device.parts import PART_NAMES, make_chip
from bmg160_emu.noise.bandwidths import BANDWIDTHS, LOWPASS_ORDER
from bmg160_emu.noise.butterworth import Butterworth
from bmg160_emu.noise.identify import identify

SAMPLES = 40_000  # per axis; three independent axes are pooled
_BW, _RATE_HBW, _FIFO_CONFIG_1 = 0x10, 0x13, 0x3E


def read_at_rest(chip, n: int) -> np.ndarray:
    """n samples of the RATE registers (one burst read per output period), deg/s."""
    period = 1.0 / chip.odr_hz
    raw = bytearray()
    for _ in range(n):
        chip.advance(period)
        raw += chip.read(0x02, 6)
    return np.frombuffer(bytes(raw), dtype="<i2").reshape(n, 3) / chip.sensitivity


def expected(chip, code: int, n: int) -> tuple[float, float, float]:
    """(std, lag-1 correlation, relative sd of the pooled sample std) at rest, analytic.

    Variance: white noise of density N through the code's filter, N^2 ODR sum(h^2); the
    counts' rounding, LSB^2 / 12, white after the filter; a Gauss-Markov term's expected
    sample variance over a record of length L, B^2 [1 - 2x + 2x^2 (1 - e^(-1/x))] with
    x = T / L; a random walk's, K^2 L / 6. The slow terms are correlated 1 from sample to
    sample (T >> 1 / ODR). The sd of a sample std of n correlated samples is about
    sqrt((1 + 2 sum rho_k^2) / 2n) of it (Bartlett), here over 3 n pooled samples."""
    odr, bandwidth = BANDWIDTHS[code]
    axis = chip.state.path.noise.generator.profile.x
    white = Butterworth(LOWPASS_ORDER, bandwidth, float(odr)).white_stats()
    scale = axis.N**2 * odr
    var_white = scale * white.variance_ratio
    cov1_white = scale * white.autocovariance[1]
    var_q = (1.0 / chip.sensitivity) ** 2 / 12.0
    length = n / odr
    slow = axis.K**2 * length / 6.0
    for B, T in axis.gauss_markov_terms:
        x = T / length
        slow += B**2 * (1 - 2 * x + 2 * x**2 * (1 - math.exp(-1 / x)))
    var = var_white + var_q + slow
    rho = white.autocovariance / white.autocovariance[0] * var_white / var
    rho_sum = float(np.sum(rho[1:] ** 2))
    return math.sqrt(var), (cov1_white + slow) / var, math.sqrt((1 + 2 * rho_sum) / (2 * 3 * n))


@pytest.mark.parametrize("code", sorted(BANDWIDTHS))
@pytest.mark.parametrize("part", PART_NAMES)
def test_noise_at_rest_follows_the_bw_register(part, code):
    chip = make_chip(part, seed=100 + code)
    chip.write(_BW, bytes([code]))
    chip.advance(0.05)  # the rate filter's start after the BW change (the noise is settled)
    data = read_at_rest(chip, SAMPLES)
    data = data - data.mean(axis=0)
    std = float(np.sqrt(np.mean(data**2)))
    lag1 = float(np.sum(data[1:] * data[:-1]) / np.sum(data**2))
    want_std, want_lag1, rel_sd = expected(chip, code, SAMPLES)
    # 2 % is at least 4 standard deviations of the pooled sample std (rel_sd <= 0.5 %)
    assert 4 * rel_sd <= 0.02
    assert std == pytest.approx(want_std, rel=0.02), (std, want_std)
    # the lag-1 correlation of 120 000 samples scatters by well under 0.005
    assert abs(lag1 - want_lag1) < 0.02, (lag1, want_lag1)


def test_the_unfiltered_path_carries_the_noise_raw():
    chip = make_chip("bmg160", seed=7)
    chip.write(_BW, bytes([4]))  # 200 Hz, 23 Hz filter
    chip.write(_RATE_HBW, bytes([0x80]))  # data_high_bw: the unfiltered data (spec 4.12)
    data = read_at_rest(chip, SAMPLES)
    data = data - data.mean(axis=0)
    axis = chip.state.path.noise.generator.profile.x
    white = axis.N**2 * 200.0 + (1.0 / chip.sensitivity) ** 2 / 12.0
    # white: the pooled sample std of 120 000 independent samples scatters by 0.2 %
    assert float(data.std()) == pytest.approx(math.sqrt(white), rel=0.02)
    lag1 = float(np.sum(data[1:] * data[:-1]) / np.sum(data**2))
    assert abs(lag1) < 0.02  # the slow terms hold 0.1 % of the variance


def test_paper_mode_stays_output_referred():
    # the paper's recursion is the chip's output (its Table 3): no filter on it, whatever BW
    stds = []
    for code in (0, 5):
        chip = make_chip("bmg160", seed=8, noise_mode="paper")
        chip.write(_BW, bytes([code]))
        data = read_at_rest(chip, 20_000)
        stds.append(float((data - data.mean(axis=0)).std()))
    # sigma_N = 0.249334 deg/s per sample at any rate (paper eq. 16), plus B and the rounding
    for std in stds:
        assert std == pytest.approx(math.hypot(0.249334, 0.004, 0.061 / math.sqrt(12)), rel=0.02)


def test_a_profile_filter_that_differs_from_the_bw_setting_is_said(caplog):
    from bmg160_emu.noise.profile import AxisNoise, OutputStage, Profile

    axis = AxisNoise(N=0.01, B=0.0, T=0.0, K=0.0, bias=0.0)
    own = Profile("mine", axis, axis, axis, output=OutputStage(order=2, corner_hz=32.0,
                                                               rate_hz=100.0))
    with caplog.at_level("INFO", logger="bmg160_emu.noise.sensor_noise"):
        chip = make_chip("bmg160", seed=1, profile=own)
        chip.write(_BW, bytes([7]))  # 100 Hz, 32 Hz: the profile's own filter
        chip.advance(0.1)
        chip.write(_BW, bytes([5]))  # 100 Hz, 12 Hz
        chip.advance(0.1)
    said = [r.getMessage() for r in caplog.records if "identified through" in r.getMessage()]
    assert any("12 Hz at 100 Hz ODR" in m for m in said), said
    assert not any("32 Hz at 100 Hz ODR" in m for m in said), said  # the same filter: quiet
    assert chip.state.path.noise.notes == said[-len(chip.state.path.noise.notes):]


def test_a_constant_rate_with_noise_off_reads_exactly_at_every_code():
    for code in sorted(BANDWIDTHS):
        chip = make_chip("bmg160", seed=1, noise=False, true_rate=(100.0, -50.0, 12.5))
        chip.write(_BW, bytes([code]))
        data = read_at_rest(chip, 300)
        assert np.all(data[-1] * chip.sensitivity == np.rint(np.array([100.0, -50.0, 12.5])
                                                             * chip.sensitivity))


@pytest.mark.slow
def test_n_b_t_k_come_back_from_a_long_register_recording():
    # 6 h at 200 Hz of the FIFO (stream mode: 100 frames per read) at BW code 4 (23 Hz):
    # identify finds the chip's filter and the counts' LSB and gives back the profile's N,
    # B, T, K within the round-trip bounds of tests/test_identify_roundtrip.py (the
    # two-sigma scatter of one 6 h, 200 Hz record: N 3 %, B 30 %, T a factor 2.5, K 35 %)
    chip = make_chip("bmg160", seed=21)
    chip.write(_BW, bytes([4]))
    chip.write(_FIFO_CONFIG_1, bytes([0x80]))
    n = 6 * 3600 * 200
    raw = bytearray()
    for _ in range(n // 100):
        chip.advance(0.5)
        raw += chip.read(0x3F, 600)
    data = np.frombuffer(bytes(raw), dtype="<i2").reshape(n, 3)[:, 0] / chip.sensitivity
    truth = chip.state.path.noise.generator.profile.x
    axis = identify(data, 200.0).axes[0]
    assert axis.output_filter is not None and axis.output_filter.order == 2
    assert axis.output_filter.corner_hz == pytest.approx(23.0, rel=0.02)
    assert axis.lsb_dps == pytest.approx(1.0 / chip.sensitivity)
    assert axis.N.value == pytest.approx(truth.N, rel=0.03)
    assert axis.B.value == pytest.approx(truth.B, rel=0.30)
    assert 1 / 2.5 < axis.T.value / truth.T < 2.5
    assert axis.K.value == pytest.approx(truth.K, rel=0.35)


@pytest.mark.parametrize("sequential", [False, True])
def test_the_filtered_noise_does_not_depend_on_how_far_ahead_it_was_drawn(sequential):
    # the chip's kernel (numpy blocks in fixed chunks) and generate's (scipy's recursion):
    # sample k is the same bits whether it was drawn in small pieces or far ahead and drawn
    # again after a change of filter at sample 5000 (SensorNoise.configure goes back)
    from bmg160_emu.noise import NoiseGenerator
    from bmg160_emu.noise.sensor_noise import SensorNoise

    def noise(pieces, ahead):
        gen = NoiseGenerator("paper", rate_hz=200.0, seed=3)
        sn = SensorNoise(gen, sequential=sequential)
        sn.configure(200.0, 23.0, 0)
        k, out = 0, []
        for n in pieces:
            _, filtered = sn.take(k, n)
            out.append(filtered.copy())
            k += n
        sn.take(k, ahead)  # drawn ahead, not used
        sn.configure(200.0, 64.0, k)  # BW 0x04 -> 0x06 at sample k: redrawn from there
        for n in (7, 3000, 9000):
            out.append(sn.take(k, n)[1].copy())
            k += n
        return np.concatenate(out)

    a = noise([5000], 1)
    b = noise([1, 2, 997, 4000], 20_000)
    assert np.array_equal(a, b)
