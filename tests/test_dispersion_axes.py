"""identify --json names axes by the record's columns; profiles and the Basilisk example by
x, y, z (issue 35: ``gyro_x`` against ``x`` was a KeyError in the example, and the
dispersion gave every axis the first axis's intervals)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from bmg160_emu.adcs.dispersion import DispersionError, NoiseDispersion, identified_axes

IDENTIFICATION = (Path(__file__).resolve().parents[1]
                  / "examples/basilisk_detumble/identification.json")


def _renamed(names):
    result = json.loads(IDENTIFICATION.read_text())
    result["axes"] = {new: result["axes"][old] for old, new in zip("xyz", names)}
    return result


@pytest.mark.parametrize("names", [("gyro_x", "gyro_y", "gyro_z"), ("wx", "wy", "wz"),
                                   ("a", "b", "c"), ("X", "Y", "Z")])
def test_axes_named_by_their_columns_are_the_profile_s_x_y_z(names):
    result = _renamed(names)
    axes = identified_axes(result)
    original = json.loads(IDENTIFICATION.read_text())["axes"]
    for axis in "xyz":  # by the letter a name ends in, else by the columns' order
        assert axes[axis] == original[axis]


def test_the_letters_win_over_the_order():
    result = _renamed(("gyro_z", "gyro_x", "gyro_y"))  # columns stored z, x, y
    original = json.loads(IDENTIFICATION.read_text())["axes"]
    axes = identified_axes(result)
    assert axes["z"] == original["x"] and axes["x"] == original["y"]


def test_the_dispersion_draws_each_axis_within_its_own_intervals():
    result = _renamed(("gyro_x", "gyro_y", "gyro_z"))
    wide = copy.deepcopy(result)
    wide["axes"]["gyro_z"]["N"] = {"value": 1.0, "ci95": [0.9, 1.1], "unit": "deg/s/sqrt(Hz)"}
    _, drawn = NoiseDispersion.from_identification(wide).draw(np.random.default_rng(0))
    assert 0.5 < drawn["N_z"] < 1.5 and drawn["N_x"] < 0.1  # not the first axis's for all


def test_a_result_without_axes_is_one_line_naming_it():
    with pytest.raises(DispersionError, match="mine.json: no 'axes' table"):
        identified_axes({"rate_hz": 100}, "mine.json")
