"""``identify --method gmwm`` as a library (issue 36): a script calling
noise.gmwm_identification gets the profile the command writes."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.cli import main
from bmg160_emu.noise import NoiseGenerator, load_profile
from bmg160_emu.noise.gmwm_identification import gmwm_identification
from bmg160_emu.noise.identify import IdentificationError, identify
from bmg160_emu.noise.profile_writer import write_profile

RATE = 200.0


@pytest.fixture(scope="module")
def record() -> np.ndarray:
    return NoiseGenerator("paper", rate_hz=RATE, seed=41).generate(10 * 60 * int(RATE))


def test_a_script_gets_the_profile_identify_gmwm_writes(tmp_path, capsys, record):
    path = tmp_path / "r.npy"
    np.save(path, record)
    written = tmp_path / "command.toml"
    assert main(["identify", str(path), "--rate", "200", "--method", "gmwm",
                 "--profile-out", str(written)]) == 0
    capsys.readouterr()

    allan = identify(record, RATE)
    result, fits = gmwm_identification(allan, record)
    scripted = tmp_path / "script.toml"
    write_profile(result.to_profile(), scripted)

    by_command, by_script = load_profile(written), load_profile(scripted)
    assert by_script.axes == by_command.axes  # every figure, bit for bit through the file
    assert by_script.output == by_command.output
    assert sorted(fits) == ["x", "y", "z"]
    assert all(a.method == "gmwm" for a in result.axes)
    # GMWM's values, not the Allan fit's (which the input keeps: a new result is returned)
    assert by_script.x.N != allan.to_profile().x.N
    assert all(a.method != "gmwm" for a in allan.axes)


def test_a_failed_axis_is_an_identification_error_naming_it(record):
    allan = identify(record[:4000, :1], RATE, axis_names=["gx"])
    with pytest.raises(IdentificationError, match="axis gx: "):
        # scales beyond the record: nothing left to fit
        gmwm_identification(allan, record[:4000, :1], tau_min_s=1e6)
