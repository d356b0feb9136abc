"""ChipConfig is the one way options become chips: CLI, trace header and rig agree."""

from __future__ import annotations

import argparse
import inspect
import json

import numpy as np
import pytest

from bmg160_emu.commands._chip_options import (
    add_chip_options,
    chips_from_args,
    header_from_chip_args,
)
from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.config import SESSION_OPTIONS, SETTING_KEYS, ChipConfig
from bmg160_emu.io.trace import TraceHeader


def _parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_chip_options(parser)
    return parser.parse_args(list(argv))


def test_the_config_has_every_constructor_option_with_the_same_default():
    # A new BMG160 option fails here until ChipConfig (and so replay) knows it.
    parameters = {
        name: p.default for name, p in inspect.signature(BMG160.__init__).parameters.items()
        if name != "self" and name not in SESSION_OPTIONS
    }
    assert set(parameters) == set(SETTING_KEYS)
    config = ChipConfig()
    for name, default in parameters.items():
        assert getattr(config, name) == default, name


def test_cli_options_and_their_trace_header_build_the_same_chips():
    args = _parse("--seed", "5", "--address", "0x68", "--address", "0x69", "--range", "500",
                  "--bandwidth", "3", "--true-rate", "1", "-2", "30", "--temperature", "40",
                  "--sensitivity", "nominal")
    direct = chips_from_args(args)
    header = TraceHeader.from_dict(json.loads(json.dumps(header_from_chip_args(args).to_dict())))
    replayed = header.build_chips()
    assert sorted(direct) == sorted(replayed) == [0x68, 0x69]
    for address, chip in direct.items():
        other = replayed[address]
        chip.advance(0.05)
        other.advance(0.05)
        assert bytes(chip.dump()) == bytes(other.dump())
        assert chip.read(0x02, 6) == other.read(0x02, 6)


def test_the_header_of_default_options_keeps_its_layout():
    entry = header_from_chip_args(_parse("--seed", "1")).to_dict()["chips"][0]
    assert list(entry) == ["settings"]
    assert entry["settings"] == {"address": 0x68, "profile": "paper", "noise": True,
                                 "noise_mode": "physical", "sensitivity": "binary",
                                 "temperature_c": 23.0}


def test_an_option_beyond_the_always_written_ones_reaches_the_header_and_back():
    config = ChipConfig(hold_data_int=True, strict=True, mounting=np.eye(3)[[1, 0, 2]],
                        true_rate_dps=(0.0, 0.0, 5.0), setup_writes=[(0x0F, b"\x02")])
    back = ChipConfig.from_dict(json.loads(json.dumps(config.to_dict())))
    assert back.hold_data_int and back.strict
    assert np.array_equal(back.mounting, config.mounting)
    assert back.true_rate_dps == (0.0, 0.0, 5.0) and back.setup_writes == [(0x0F, b"\x02")]
    a, b = config.build(3), back.build(3)
    a.advance(0.02)
    b.advance(0.02)
    assert a.read(0x02, 6) == b.read(0x02, 6)


def test_a_function_of_time_cannot_go_into_a_trace():
    with pytest.raises(ValueError, match="temperature_c as a function"):
        ChipConfig(temperature_c=lambda t: 20.0 + t).to_dict()


def test_unknown_settings_are_refused():
    with pytest.raises(ValueError, match="cannot carry: \\['colour'\\]"):
        ChipConfig.from_dict({"settings": {"colour": "blue"}})
