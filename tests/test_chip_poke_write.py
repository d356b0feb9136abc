"""``poke`` (an upset) and bus writes share one change-effect table (``regmap.EFFECTS``): a
poke that leaves a register with the content a write would leave gives the same chip."""

import random

import numpy as np
import pytest

from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.registers import BY_NAME, REGISTERS, RESET_VALUES

# A bus write to these also empties the FIFO (4.26); an upset does not.
WRITE_ACTION_ONLY = {"FIFO_CONFIG_0", "FIFO_CONFIG_1"}
# Written last, LPM2 before LPM1: in (deep) suspend a write to other registers is ignored (6.7).
POWER = ("LPM2", "LPM1")


def _pair(seed: int) -> tuple[BMG160, BMG160]:
    chips = [BMG160(seed=seed, true_rate=(3.0, -1.5, 40.0)) for _ in range(2)]
    for chip in chips:
        chip.seen = []  # the rates (deg/s, before scaling) as sample hooks see them
        chip.sample_hooks.append(lambda c, t, rate: c.seen.append(rate.copy()))
        chip.advance(0.0123)  # some samples produced, a running filter, a block computed ahead
        chip.set_true_rate((-7.25, 12.5, 3.0))  # a step: the filter settles onto a new level
        chip.advance(0.05)
    return chips[0], chips[1]


def _stored(name: str, value: int) -> int:
    """What a write of ``value`` leaves in a register at its reset content."""
    reg = BY_NAME[name]
    return (RESET_VALUES[reg.address] & ~reg.write_mask) | (value & reg.write_mask)


def _same_from_now_on(a: BMG160, b: BMG160, rng: random.Random) -> None:
    assert a.dump() == b.dump()
    for _ in range(60):
        step = rng.choice([0.0004, 0.001, 0.0025, 0.013])
        a.advance(step)
        b.advance(step)
        assert a.read(0x02, 6) == b.read(0x02, 6)
        assert (a.int1, a.int2) == (b.int1, b.int2)
        assert a.dump() == b.dump()
    assert len(a.seen) == len(b.seen) > 100
    assert all(np.array_equal(x, y) for x, y in zip(a.seen, b.seen))


@pytest.mark.parametrize("seed", range(16))
def test_poke_and_write_of_every_writable_register_give_identical_chips(seed):
    # 16 seeded orders and values: each register gets 16 random contents, in random order
    rng = random.Random(seed)
    a, b = _pair(seed)
    names = [r.name for r in REGISTERS
             if r.write_mask and r.name not in WRITE_ACTION_ONLY and r.name not in POWER]
    rng.shuffle(names)
    names += POWER if rng.random() < 0.5 else ()
    for name in names:
        content = _stored(name, rng.randrange(256))
        a.write(BY_NAME[name].address, [content])
        b.poke(BY_NAME[name].address, content)
    _same_from_now_on(a, b, rng)


@pytest.mark.parametrize("name, content", [
    ("RANGE", 0xB8),  # fixed bits 7:3 only: the sensitivity stays (4.8)
    ("RANGE", 0x05),  # reserved code 5 produces data as code 0, +-2000 deg/s (4.8)
    ("TRIM_GP0", 0xA0),  # gp0, general-purpose bits beside the offset bits (4.24)
    ("TRIM_GP1", 0x5A),  # general-purpose byte (4.24)
])
@pytest.mark.parametrize("how", ["write", "poke"])
def test_content_without_effect_on_the_data_leaves_every_sample_bit_exact(name, content, how):
    seen: dict[str, list[np.ndarray]] = {"touched": [], "untouched": []}
    chips = {}
    for key, rates in seen.items():
        chip = BMG160(seed=4, true_rate=(3.0, -1.5, 40.0))
        chip.sample_hooks.append(lambda c, t, rate, out=rates: out.append(rate.copy()))
        chip.advance(0.0123)
        chip.set_true_rate((-7.25, 12.5, 3.0))  # a step: the filter settles onto a new level
        chip.advance(0.05)
        chips[key] = chip
    getattr(chips["touched"], how)(BY_NAME[name].address,
                                   [content] if how == "write" else content)
    for chip in chips.values():
        chip.advance(0.2)
    # deg/s before scaling, as hooks see them: the same floats, not only the same counts
    assert len(seen["touched"]) == len(seen["untouched"]) > 400
    assert all(np.array_equal(x, y) for x, y in zip(seen["touched"], seen["untouched"]))
