"""Every duration option takes a value that starts with '-' as a duration and refuses it in
one line (it used to be argparse's "expected one argument"), and the record and generate
help texts state their different default rates."""

from __future__ import annotations

import pytest

from bmg160_emu.cli import build_parser, main

# (arguments before the duration option, the option): every command with a duration option
DURATION_OPTIONS = [
    (["record", "-o", "out.csv"], "--duration"),
    (["generate", "-o", "out.npy"], "--duration"),
    (["identify", "missing.csv"], "--skip"),
    (["identify", "missing.csv", "--curve", "--rate", "100"], "--duration"),
    (["thermal", "missing.csv"], "--block"),
    (["stub", "--bus", "0"], "--duration"),
    (["vhost-user-i2c", "--socket", "vu.sock"], "--duration"),
]


def _error(argv, capsys) -> str:
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's own usage errors
        status = exc.code
    assert status == 2
    return capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize("value", ["-5s", "-1.5min", "-2"])
@pytest.mark.parametrize(("argv", "option"), DURATION_OPTIONS)
def test_a_negative_duration_is_refused_in_one_line_naming_the_option(
        argv, option, value, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = _error([*argv, option, value], capsys)
    assert "expected one argument" not in line
    assert option in line and "must be" in line and "positive" in line and repr(value) in line


@pytest.mark.parametrize(("argv", "option"), DURATION_OPTIONS)
def test_the_equals_form_says_the_same(argv, option, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert _error([*argv, f"{option}=-5s"], capsys) == _error([*argv, option, "-5s"], capsys)


def test_a_duration_option_still_refuses_a_missing_value(capsys):
    assert "expected one argument" in _error(["record", "-o", "x.csv", "--duration", "-o"], capsys)


def test_record_and_generate_state_their_default_rates():
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    record_help = " ".join(commands["record"].format_help().split())
    generate_help = " ".join(commands["generate"].format_help().split())
    assert "default: the chip's reset BW 0x00, 2000 Hz" in record_help
    assert "(default 200)" in generate_help


def test_stub_help_has_examples():
    commands = build_parser()._subparsers._group_actions[0].choices
    assert "\nexamples" in commands["stub"].format_help()
