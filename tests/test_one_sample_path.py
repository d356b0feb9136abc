"""The data path's one-sample piece (a closed loop's step) in Python floats: bit for bit what
the block path computes for that sample, so streams do not depend on which path ran.

Each test compares the fast code with the general one on random inputs with fixed seeds; a
difference of one rounding step anywhere fails (``array_equal`` / ``==`` on floats).
"""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.device import datapath
from bmg160_emu.noise import lowpass
from bmg160_emu.noise.bandwidths import BANDWIDTHS, BW_CODES


def _filter(code: int, rng: np.random.Generator) -> lowpass.LowPass:
    odr, bandwidth = BANDWIDTHS[code]
    f = lowpass.LowPass(odr, bandwidth)
    f.restart(rng.normal(0.0, 100.0, 3))
    f.state = rng.normal(0.0, 5.0, f.state.shape)
    return f


@pytest.mark.parametrize("code", BW_CODES)
def test_filter_step_is_the_first_row_of_a_block_run(code: int) -> None:
    rng = np.random.default_rng(code)
    for _ in range(300):
        f = _filter(code, rng)
        x = rng.normal(0.0, 200.0, (1, 3)) * 10.0 ** rng.integers(-6, 3)
        y_block, state_block = f.run(x)
        y = f.step(x[0].tolist())
        assert y == y_block[0].tolist()
        assert np.array_equal(f.state, state_block)


@pytest.mark.parametrize("code", [0, 4])
def test_filter_steps_in_a_row_are_a_closed_loops_one_sample_blocks(code: int) -> None:
    # a filter at rest, then 200 samples one at a time, against 200 one-row runs
    rng = np.random.default_rng(10 + code)
    fast, slow = _filter(code, rng), _filter(code, rng)
    slow.reference, slow.state = fast.reference.copy(), fast.state.copy()
    for x in rng.normal(0.0, 50.0, (200, 3)):
        y_block, slow.state = slow.run(x[None, :])
        assert fast.step(x.tolist()) == y_block[0].tolist()
    assert np.array_equal(fast.state, slow.state)


def _rebase_reference(f: lowpass.LowPass, level: np.ndarray) -> bool:
    """Whether the allclose test of the earlier implementation re-references at ``level``."""
    deviation = level - f.reference
    if not deviation.any() and not f.state.any():
        return False
    settled = np.outer(f._zi_unit, deviation)
    return bool(np.allclose(f.state, settled, rtol=0.0,
                            atol=1e-12 * max(1.0, np.abs(deviation).max())))


@pytest.mark.parametrize("code", BW_CODES)
def test_rebase_if_settled_decides_as_allclose(code: int) -> None:
    rng = np.random.default_rng(100 + code)
    decided = set()
    for i in range(400):
        f = _filter(code, rng)
        level = f.reference + rng.normal(0.0, 30.0, 3)
        # settled states, some a hair off the tolerance on one entry, some far off
        f.state = np.outer(f._zi_unit, level - f.reference)
        scale = 1e-12 * max(1.0, np.abs(level - f.reference).max())
        f.state[i % 2, i % 3] += scale * rng.choice([0.0, 0.5, 0.999, 1.001, 2.0, 1e6])
        expected = _rebase_reference(f, level)
        before = f.reference.copy()
        f.rebase_if_settled(level)
        assert np.array_equal(f.reference, level if expected else before)
        decided.add(expected)
    assert decided == {True, False}


def test_counts_of_is_to_counts_and_to_bytes() -> None:
    rng = np.random.default_rng(5)
    values = np.concatenate([
        rng.normal(0.0, 100.0, 3000),
        np.arange(-40.0, 40.0, 0.5) / 131.0 * 131.0,  # halves: round half to even
        [250.1, -250.2, 1e300, -1e300, np.inf, -np.inf, 0.0, -0.0],
    ])
    values = np.resize(values, (len(values) // 3 + 1) * 3).reshape(-1, 3)
    for sensitivity in (131.072, 16.384, 1.0):
        for row in values:
            with np.errstate(over="ignore"):
                counts = datapath.to_counts(row[None, :], sensitivity)
            got_counts, got_bytes = datapath.counts_of(row.tolist(), sensitivity)
            assert got_counts == tuple(int(c) for c in counts[0])
            assert got_bytes == datapath.to_bytes(counts)


def test_a_one_sample_block_is_the_first_sample_of_a_long_block() -> None:
    # one DataPath built twice from the same state: n = 1 (Python floats) and n = 63 (arrays);
    # the noise of both is the same buffered draw
    rng = np.random.default_rng(7)

    for high_bw in (False, True):
        for offset in (np.zeros(3), np.array([0.061, -0.122, 0.0])):
            mounting = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
            generator = datapath.noise_generator("paper", "physical", 3, 0x68)
            path = datapath.DataPath(mounting, generator, None)
            path.set_filter(4, used_end=0)  # 200 Hz, 23 Hz
            body = rng.normal(0.0, 40.0, (64, 3))
            path.build(0, body[:1], offset, 131.072, high_bw, False)  # filter started
            state = path.filter.state.copy()
            one = path.build(1, body[1:2], offset, 131.072, high_bw, False)
            path.filter.state = state
            many = path.build(1, body[1:], offset, 131.072, high_bw, False)
            assert one.rate_bytes == many.rate_bytes[:6]
            for name in ("y", "dps_f", "dps_u"):
                assert list(getattr(one, name)[0]) == getattr(many, name)[0].tolist()
            for name in ("counts_f", "counts_u"):
                assert list(getattr(one, name)[0]) == getattr(many, name)[0].tolist()
