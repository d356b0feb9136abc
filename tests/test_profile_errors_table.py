"""A profile's [errors] table (issue 16) and the bounds that keep every sample finite
(issue 12: N = 1e308 passed validation and generate wrote inf samples with exit 0)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from bmg160_emu.device.chip import BMG160
from bmg160_emu.noise import NoiseGenerator, load_profile
from bmg160_emu.noise.profile import LIMITS, ProfileError
from bmg160_emu.noise.profile_writer import format_profile
from bmg160_emu.noise.sensor_errors import SensorErrors


def test_the_datasheet_unit_profile_carries_every_error_term_with_its_source():
    profile = load_profile("datasheet_unit")
    errors = SensorErrors.from_dict(profile.errors)
    assert errors.zero_rate_offset_dps == (1.0, -1.0, 1.0)  # +-1 deg/s typ (table 1)
    assert errors.bias_tc_dps_per_k[0][0] == 0.015  # TCO +-0.015 deg/s/K typ
    assert errors.g_sensitivity_dps_per_g[0][0] == pytest.approx(0.1 / 3, abs=1e-4)
    assert "BST-BMG160-DS000-09" in errors.source
    chip = BMG160(seed=1, profile="datasheet_unit", noise=False, temperature_c=35.0)
    assert chip.sensor_errors == errors
    chip.advance(0.05)
    rate = np.frombuffer(chip.read(0x02, 6), "<i2") / chip.sensitivity
    # offset + TCO x 10 K, at one count of +-2000 deg/s (0.061 deg/s)
    assert np.allclose(rate, [1.15, -1.15, 1.15], atol=0.061)


def test_an_errors_table_round_trips_through_the_profile_file(tmp_path):
    profile = load_profile("datasheet_unit")
    path = tmp_path / "unit.toml"
    path.write_text(format_profile(profile))
    again = load_profile(path)
    assert SensorErrors.from_dict(again.errors) == SensorErrors.from_dict(profile.errors)


def test_a_bad_errors_table_is_refused_naming_the_file_and_table(tmp_path, capsys):
    # the noise layer checks its own [errors] table on loading (issue 36): the chip, generate
    # and any other reader of the profile refuse it alike, naming the file
    text = format_profile(load_profile("datasheet")) + "\n[errors]\nzero_rate_offset = 1\n"
    path = tmp_path / "bad.toml"
    path.write_text(text)
    message = r"profile file .*bad\.toml \[errors\]: unknown keys \['zero_rate_offset'\]"
    with pytest.raises(ProfileError, match=message):
        load_profile(path)
    with pytest.raises(ProfileError, match=message):
        BMG160(seed=1, profile=path)
    from bmg160_emu.cli import main

    assert main(["generate", "--profile", str(path), "--duration", "1s", "--seed", "1",
                 "-o", str(tmp_path / "n.npy")]) != 0
    assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "n.npy").exists()


@pytest.mark.parametrize(("key", "value"), [("N", 1e308), ("B", 1e4), ("K", 2.0),
                                            ("bias", -1e5), ("T", 1e-9), ("T", 1e14)])
def test_parameters_beyond_their_bound_are_refused_by_name(tmp_path, key, value):
    text = format_profile(load_profile("datasheet")).replace(
        f"\n{key} = ", f"\n{key} = {value!r}  # was ", 1)
    path = tmp_path / "p.toml"
    path.write_text(text)
    with pytest.raises(ProfileError, match=f"{key} must be"):
        load_profile(path)


def test_at_every_bound_the_samples_stay_finite():
    worst = {axis: {"N": LIMITS["N"], "B": LIMITS["B"], "T": 1e-6, "K": LIMITS["K"],
                    "bias": LIMITS["bias"], "Q": LIMITS["Q"], "R": LIMITS["R"]}
             for axis in "xyz"}
    for rate_hz in (100.0, 2000.0):
        out = NoiseGenerator(profile={"name": "worst", **worst}, rate_hz=rate_hz, seed=1).generate(
            20000)
        assert np.all(np.isfinite(out))


def test_paper_mode_on_a_profile_without_its_fields_is_a_profile_error():
    with pytest.raises(ProfileError, match="paper mode needs sigma_gyro and sigma_K"):
        NoiseGenerator(profile="datasheet", rate_hz=200.0, seed=1, mode="paper").generate(10)
