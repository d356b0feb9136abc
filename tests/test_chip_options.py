"""The shared command-line chip options (bmg160_emu.commands._chip_options)."""

import argparse
import struct

import pytest

from bmg160_emu.commands._chip_options import add_chip_options, chips_from_args


def _parse(*argv):
    parser = argparse.ArgumentParser()
    add_chip_options(parser)
    return parser.parse_args(list(argv))


def test_defaults_give_one_noisy_chip_at_0x68():
    chips = chips_from_args(_parse("--seed", "1"))
    assert list(chips) == [0x68] and chips[0x68].state.path.noise.generator is not None


def test_two_addresses_share_one_clock():
    chips = chips_from_args(_parse("--address", "0x68", "--address", "0x69", "--seed", "3"))
    assert chips[0x68].clock is chips[0x69].clock


def test_options_configure_rate_range_and_bandwidth():
    args = _parse("--no-noise", "--true-rate", "10", "0", "-5", "--range", "250",
                  "--bandwidth", "4", "--sensitivity", "nominal")
    chip = chips_from_args(args)[0x68]
    chip.advance(1.0)
    assert chip.read(0x0F)[0] == 3 and chip.odr_hz == 200
    assert struct.unpack("<3h", chip.read(0x02, 6)) == (round(10 * 131.2), 0, round(-5 * 131.2))


@pytest.mark.parametrize("argv", [["--address", "0x50"], ["--range", "300"],
                                  ["--bandwidth", "9"], ["--address", "zz"]])
def test_bad_options_are_argparse_errors(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        _parse(*argv)
    assert exc.value.code == 2


def test_realtime_option_uses_a_real_time_clock():
    chip = chips_from_args(_parse("--realtime", "--no-noise"))[0x68]
    assert chip.clock.realtime


def test_unknown_profile_is_a_command_error():
    from bmg160_emu.commands._common import CommandError

    with pytest.raises(CommandError):
        chips_from_args(_parse("--profile", "no-such-profile"))


@pytest.mark.parametrize(("command", "offered"),
                         [("run", False), ("stub", False), ("record", False), ("dump", True)])
def test_realtime_is_offered_only_where_it_means_something(command, offered):
    # run answers on its own request clock, stub always lives in real time and record in
    # virtual time: --realtime did nothing in the first two and was refused by the third
    from bmg160_emu.cli import build_parser

    subparsers = next(a for a in build_parser()._actions
                      if isinstance(a, argparse._SubParsersAction))
    options = {o for action in subparsers.choices[command]._actions for o in action.option_strings}
    assert ("--realtime" in options) == offered
