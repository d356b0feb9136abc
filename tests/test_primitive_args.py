"""The chip primitives' argument rules (one module shared by the model and the simulated firmware)."""

import numpy as np
import pytest

from bmg160_emu import BMG160
from bmg160_emu.device.contract import check_count, check_data, check_register


@pytest.mark.parametrize("bad, error", [(True, TypeError), ("2", TypeError), (1.0, TypeError),
                                        (-1, ValueError), (0x100, ValueError)])
def test_bad_registers_are_refused(bad, error):
    with pytest.raises(error):
        check_register(bad)


def test_registers_accept_any_integer_type():
    assert check_register(np.uint8(0x3F)) == 0x3F


@pytest.mark.parametrize("bad, error", [(False, TypeError), (2.5, TypeError), (-1, ValueError)])
def test_bad_byte_counts_are_refused(bad, error):
    with pytest.raises(error):
        check_count(bad)


@pytest.mark.parametrize("bad, error", [(5, TypeError), ("ab", TypeError), ([256], ValueError)])
def test_bad_data_is_refused(bad, error):
    with pytest.raises(error):
        check_data(bad)


def test_the_chip_primitives_apply_the_shared_rules():
    chip = BMG160(seed=1, noise=False)
    with pytest.raises(ValueError, match="out of range"):
        chip.read(0x100, 1)
    with pytest.raises(TypeError, match="byte count"):
        chip.read(0x00, 1.5)
    with pytest.raises(ValueError, match="0..255"):
        chip.write(0x0F, [300])
    assert chip.read(np.int64(0), 1) == b"\x0f"
