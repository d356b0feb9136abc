"""A closed loop's true rate, one constant per step (``set_true_rate`` between samples), gives
the samples the same rates given up front as rows (one per output sample) give: the model
recomputes only what a step changes, not the samples it had computed ahead."""

import numpy as np
import pytest

from bmg160_emu.device.chip import BMG160


def _rates(n: int, seed: int) -> np.ndarray:
    # a random walk in deg/s: no two consecutive rows equal, as a simulator's rate
    steps = np.random.default_rng(seed).normal(0.0, 3.0, size=(n, 3))
    return np.cumsum(steps, axis=0) + np.array([10.0, -20.0, 5.0])


@pytest.mark.parametrize("bw", [0x04, 0x01])  # 200 Hz and 2000 Hz ODR
@pytest.mark.parametrize("hooks", [False, True])
def test_set_true_rate_each_step_gives_the_samples_of_the_rows(bw, hooks):
    rates = _rates(600, seed=bw)
    stepped = BMG160(seed=11, true_rate=rates[0])
    rows = BMG160(seed=11, true_rate=rates)
    seen: dict[int, list[np.ndarray]] = {id(stepped): [], id(rows): []}
    for chip in (stepped, rows):
        chip.write(0x10, bytes([bw]))  # at t = 0: sample 0 is already out at BW code 0
        if hooks:  # the per-sample route, with the rates (deg/s) as hooks see them
            chip.sample_hooks.append(lambda c, t, r: seen[id(c)].append(r.copy()))
    period = 1.0 / stepped.odr_hz
    for k in range(1, len(rates)):
        stepped.set_true_rate(rates[k])
        for chip in (stepped, rows):
            chip.advance(period)
        assert stepped.read(0x02, 6) == rows.read(0x02, 6), k
    assert stepped.dump() == rows.dump()
    if hooks:
        assert len(seen[id(stepped)]) == len(seen[id(rows)]) == len(rates) - 1
        assert all(np.array_equal(a, b) for a, b in zip(seen[id(stepped)], seen[id(rows)]))


def test_a_rate_held_after_the_steps_goes_on_as_the_last_row():
    # after the loop stops, long advances use large pieces again; the samples stay those of
    # the rows' last value held
    rates = _rates(50, seed=3)
    stepped = BMG160(seed=2, true_rate=rates[0])
    rows = BMG160(seed=2, true_rate=rates)
    for chip in (stepped, rows):
        chip.write(0x3E, bytes([0x80]))  # stream mode: the FIFO keeps the last 100 frames
    period = 1.0 / stepped.odr_hz
    for k in range(1, len(rates)):
        stepped.set_true_rate(rates[k])
        stepped.advance(period)
        rows.advance(period)
    for seconds in (0.3, 1.7, 0.0005):
        stepped.advance(seconds)
        rows.advance(seconds)
        assert stepped.read(0x3F, 600) == rows.read(0x3F, 600)
        assert stepped.dump() == rows.dump()
