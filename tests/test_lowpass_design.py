"""The chip's low-pass without scipy: design and filtering agree with scipy.signal to rounding.

scipy may be imported here (it is the reference); the chip path itself must not need it
(tests/test_import_cost.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from bmg160_emu.noise import butterworth, lowpass
from bmg160_emu.noise.bandwidths import BANDWIDTHS, LOWPASS_ORDER

EPS = np.finfo(float).eps


@pytest.mark.parametrize("code", sorted(BANDWIDTHS))
def test_coefficients_of_every_bw_code_are_scipy_butter(code: int) -> None:
    odr, bandwidth = BANDWIDTHS[code]
    b, a, zi = lowpass.coefficients(float(odr), float(bandwidth))
    b_ref, a_ref = signal.butter(LOWPASS_ORDER, bandwidth / (odr / 2.0))
    # Same operations in the same order as scipy's butter -> bilinear_zpk -> zpk2tf, so the
    # difference is a few rounding steps of numbers of order 1.
    np.testing.assert_allclose(b, b_ref, rtol=0, atol=4 * EPS)
    np.testing.assert_allclose(a, a_ref, rtol=0, atol=4 * EPS)
    np.testing.assert_allclose(zi, signal.lfilter_zi(b_ref, a_ref), rtol=0, atol=16 * EPS)


@pytest.mark.parametrize("order", [1, 2, 3, 4, 6])
@pytest.mark.parametrize("wn", [0.02, 0.23, 0.5, 0.9])
def test_butterworth_of_any_order_is_scipy_butter(order: int, wn: float) -> None:
    b, a = butterworth.butterworth(order, wn)
    b_ref, a_ref = signal.butter(order, wn)
    # coefficients grow like binomial numbers with the order: compare relative to the largest
    np.testing.assert_allclose(b, b_ref, rtol=0, atol=8 * EPS * np.abs(b_ref).max())
    np.testing.assert_allclose(a, a_ref, rtol=0, atol=8 * EPS * np.abs(a_ref).max())


@pytest.mark.parametrize("wn", [0.0, 1.0, -0.1, 1.5])
def test_butterworth_refuses_a_cut_off_outside_the_band(wn: float) -> None:
    with pytest.raises(ValueError, match="between 0 and 1"):
        butterworth.butterworth(2, wn)


L = lowpass.SUB_BLOCK
CHUNK = lowpass.SUB_BLOCK * lowpass.SUB_BLOCKS
LENGTHS = [1, 2, L - 1, L, L + 1, 3 * L + 5, CHUNK - 1, CHUNK, CHUNK + 1, 3 * CHUNK + 17]


@pytest.mark.parametrize("code", sorted(BANDWIDTHS))
@pytest.mark.parametrize("n", LENGTHS)
def test_block_filter_matches_lfilter(code: int, n: int) -> None:
    odr, bandwidth = BANDWIDTHS[code]
    filt = lowpass.LowPass(odr, bandwidth)
    rng = np.random.default_rng(1000 * code + n)
    x = 300.0 * rng.standard_normal((n, 3)) + rng.uniform(-50, 50, 3)
    state = 10.0 * rng.standard_normal((len(filt.a) - 1, 3))
    y, final = filt.run(x, state)
    y_ref, final_ref = signal.lfilter(filt.b, filt.a, x, axis=0, zi=state)
    # Rounding differs (sums in another order) by about 1e-16 of the signal's size; 1e-12 of
    # it is far below one LSB at any range (1 LSB >= 1/262 deg/s, signals here ~1000 deg/s).
    scale = np.abs(y_ref).max()
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(final, final_ref, rtol=0, atol=1e-12 * np.abs(final_ref).max())


@pytest.mark.parametrize("order", [1, 3, 4])
def test_block_filter_of_other_orders_matches_lfilter(order: int) -> None:
    b, a = butterworth.butterworth(order, 0.2)
    blocks = lowpass._Blocks(b, a)
    rng = np.random.default_rng(order)
    x = rng.standard_normal((2 * CHUNK + 77, 2))
    state = rng.standard_normal((order, 2))
    y, final = blocks.run(x, state)
    y_ref, final_ref = signal.lfilter(b, a, x, axis=0, zi=state)
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e-12 * np.abs(y_ref).max())
    np.testing.assert_allclose(final, final_ref, rtol=0, atol=1e-12 * np.abs(final_ref).max())


def test_filtering_in_pieces_continues_the_same_output() -> None:
    filt = lowpass.LowPass(200, 23.0)
    rng = np.random.default_rng(5)
    x = rng.standard_normal((5000, 3))
    whole, end = filt.run(x, np.zeros((2, 3)))
    parts, state = [], np.zeros((2, 3))
    for cut in np.split(np.arange(5000), [7, 40, 1100, 1101, 3000]):
        y, state = filt.run(x[cut], state)
        parts.append(y)
    np.testing.assert_allclose(np.concatenate(parts), whole, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state, end, rtol=0, atol=1e-12)


def test_empty_input_keeps_the_state() -> None:
    filt = lowpass.LowPass(100, 12.0)
    state = np.ones((2, 3))
    y, final = filt.run(np.empty((0, 3)), state)
    assert y.shape == (0, 3)
    np.testing.assert_array_equal(final, state)


def test_a_constant_at_the_reference_passes_bit_exactly() -> None:
    filt = lowpass.LowPass(400, 47.0)
    level = np.array([1.0 / 3.0, -250.125, 1e-7])
    filt.restart(level)
    y, _ = filt.run(np.tile(level, (3000, 1)))
    assert (y == level).all()


def test_the_settled_state_is_what_a_long_constant_input_leaves() -> None:
    filt = lowpass.LowPass(200, 64.0)
    _, state = filt.run(np.ones((4000, 3)), np.zeros((2, 3)))
    np.testing.assert_allclose(state, np.outer(filt._zi_unit, np.ones(3)), rtol=0, atol=1e-12)
