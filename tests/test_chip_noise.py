"""Noise on the output: seeded, independent per address, polling-pattern invariant."""

import numpy as np
from _chip_helpers import period_s, rates

from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.chip import BMG160


def _series(chip, n, step=1):
    out = []
    for _ in range(n):
        chip.advance(step * period_s(chip))
        out.append(rates(chip))
    return np.array(out, dtype=float)


def test_same_seed_and_address_give_the_same_output():
    a, b = BMG160(seed=5), BMG160(seed=5)
    assert np.array_equal(_series(a, 200), _series(b, 200))


def test_two_chips_with_one_master_seed_have_independent_noise():
    clock = VirtualClock()
    a = BMG160(seed=5, clock=clock, address=0x68)
    b = BMG160(seed=5, clock=clock, address=0x69)
    xa, xb = [], []
    for _ in range(2000):
        a.advance(period_s(a))
        xa.append(rates(a))
        xb.append(rates(b))
    xa = np.array(xa, dtype=float)[:, 0]
    xb = np.array(xb, dtype=float)[:, 0]
    corr = np.corrcoef(xa - xa.mean(), xb - xb.mean())[0, 1]
    # 2000 independent pairs: |r| has std 1/sqrt(2000) = 0.022; 0.1 is > 4 sigma
    assert abs(corr) < 0.1


def test_noise_does_not_depend_on_the_polling_pattern():
    a, b = BMG160(seed=9), BMG160(seed=9)
    a.write(0x3E, b"\x80")
    b.write(0x3E, b"\x80")
    a.advance(100 * period_s(a))
    for _ in range(100):
        b.advance(period_s(b))
    assert a.read(0x3F, 600) == b.read(0x3F, 600)


def _stream_after_odr_changes(advances):
    chip = BMG160(seed=9)
    for seconds in advances:  # the data path computes ahead by as much as each advance needs
        chip.advance(seconds)
    out = []
    for bw in (b"\x04", b"\x00", b"\x05"):  # 200, 2000, 100 Hz
        chip.write(0x10, bw)
        for _ in range(50):
            chip.advance(period_s(chip))
            out.append(chip.read(0x02, 6))
    return out


def test_noise_after_an_odr_change_does_not_depend_on_the_polling_pattern():
    one_long = _stream_after_odr_changes([0.6])
    many_short = _stream_after_odr_changes([0.001] * 600)
    assert one_long == many_short


def test_noise_false_gives_a_noiseless_chip():
    chip = BMG160(seed=1, noise=False)
    assert not _series(chip, 100).any()


def test_noise_level_matches_the_profile_white_noise():
    chip = BMG160(seed=2)
    chip.write(0x13, b"\x80")  # unfiltered, so the output noise is the profile's
    chip.write(0x0F, b"\x04")
    x = _series(chip, 4000)[:, 0] / chip.sensitivity
    # paper N = 0.01779 deg/s/sqrt(Hz) at 2000 Hz -> sigma 0.796 deg/s; 4000 samples give the
    # std to ~1.1 %; 10 % allows for the other noise terms and quantisation
    assert abs(x.std() / (0.01779073 * np.sqrt(2000)) - 1) < 0.10
