"""The command line against hostile files and numbers (issue 24): every input format the CLI
reads and every numeric option end in exit 0 or one error line (exit 1 or 2), never a
traceback, a leaked RuntimeWarning or a hang (tests/_fuzz_cli.py has the harness;
``python tools/fuzz.py --cli`` runs a long campaign).

CI budget: the formats' own seeds rewritten with CR-only and mixed line endings, 5 mutated
files per format (fixed seeds), the declared-size attacks, and 10 bad values per numeric
option; about 60 s on one core."""

from __future__ import annotations

import argparse
import random

import pytest
from _fuzz_cli import (
    BAD_NUMBERS,
    CLI_FORMATS,
    NUMERIC_OPTIONS,
    classify,
    cli_seed_folder,
    declared_size,
    expand,
    fuzz_format,
    fuzz_option,
    line_endings,
    run_in_process,
    run_subprocess,
)

MUTATED_PER_FORMAT = 5
CI_VALUES = ("nan", "inf", "-inf", "0", "-1", "1e308", "1e23", str(2**63), "1e9d", "1_000")
TEXT_FORMATS = [f for f in CLI_FORMATS if f.text]


def _assert_fine(what, outcome):
    assert not outcome.broken, f"{outcome.kind}: {outcome.detail}\n  from {what}"


def test_the_formats_listed_are_every_format_the_cli_reads():
    # 17 formats in the issue; CSV-like files read by different commands count apart
    assert len(CLI_FORMATS) >= 17
    assert len({f.name for f in CLI_FORMATS}) == len(CLI_FORMATS)


def _numeric_actions():
    from bmg160_emu.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in sub.choices.items():
        parsers = [(name, command)]
        inner = [a for a in command._actions if isinstance(a, argparse._SubParsersAction)]
        for action in inner:
            parsers += [(f"{name} {n}", p) for n, p in action.choices.items()]
        for label, p in parsers:
            for action in p._actions:
                if action.help == argparse.SUPPRESS:
                    continue  # an old spelling kept hidden for a release: its new one is here
                if action.type in (int, float):
                    yield label, action, "raw"
                elif action.type is not None and action.option_strings and \
                        getattr(action.type, "__module__", "") == "bmg160_emu.commands._common" \
                        and action.type.__name__ != "duration":
                    yield label, action, "bounded"


def test_no_option_reads_a_number_without_a_stated_range():
    raw = [f"{label} {a.option_strings[0]}" for label, a, kind in _numeric_actions()
           if kind == "raw"]
    assert raw == [], "numeric options without limits.Bounded"


# the emulated chip's options (commands/_chip_options.py) are one parser shared by every
# command: fuzzed through one command each (dump, record)
SHARED = {"seed", "true_rate", "temperature", "bus"}


def test_every_bounded_option_is_fuzzed():
    missing = [f"{label} {a.option_strings[-1]}" for label, a, _ in _numeric_actions()
               if not any(f"{label} {o}" in NUMERIC_OPTIONS for o in a.option_strings)
               and a.dest not in SHARED]
    assert missing == []


@pytest.mark.parametrize("option", sorted(NUMERIC_OPTIONS))
def test_bad_values_of_a_numeric_option_end_in_one_line(option, tmp_path):
    for value in CI_VALUES:
        _assert_fine(*fuzz_option(option, value, tmp_path))


def test_every_bad_value_is_tried_somewhere():
    assert set(CI_VALUES) <= set(BAD_NUMBERS)


@pytest.mark.parametrize("fmt", TEXT_FORMATS, ids=[f.name for f in TEXT_FORMATS])
def test_cr_only_and_mixed_line_endings(fmt, tmp_path):
    data = (cli_seed_folder() / fmt.seed).read_bytes()
    for seed in (0, 3):  # random.Random(0) picks CR only, random.Random(3) the mix
        rewritten = line_endings(data, random.Random(seed))
        assert b"\r" in rewritten
        path = tmp_path / fmt.seed.split("/")[-1]
        if fmt.name == "dynamics-table":
            continue  # read through its scenario: covered by the mutated files below
        path.write_bytes(rewritten)
        for command in fmt.commands:
            argv = expand(command, path, tmp_path)
            _assert_fine(argv, run_in_process(argv))


@pytest.mark.parametrize("fmt", CLI_FORMATS, ids=[f.name for f in CLI_FORMATS])
def test_mutated_files(fmt, tmp_path):
    for seed in range(MUTATED_PER_FORMAT):
        _assert_fine(*fuzz_format(fmt, 7919 * seed, tmp_path))


@pytest.mark.parametrize("name,command", [
    ("rates-npy", ("identify", "{}", "--rate", "200", "--poles", "1")),
    ("recording-npz", ("identify", "{}", "--poles", "1")),
    ("recording-npz", ("replay", "{}", "--script", "{seeds}/short.script", "--seed", "1")),
    ("recording-csv", ("replay", "{}", "--script", "{seeds}/short.script", "--seed", "1")),
    ("recording-csv", ("replay", "{}", "--seed", "1", "-o", "{tmp}/out.npz")),
])
def test_declared_sizes_and_shapes(name, command, tmp_path):
    fmt = next(f for f in CLI_FORMATS if f.name == name)
    data = (cli_seed_folder() / fmt.seed).read_bytes()
    for seed in range(8):
        path = tmp_path / fmt.seed.split("/")[-1]
        path.write_bytes(declared_size(name, data, random.Random(seed)))
        argv = expand(command, path, tmp_path)
        _assert_fine(argv, run_in_process(argv))


def test_a_script_interval_that_rounds_to_zero_is_refused_not_looped(tmp_path):
    # `poll ... every 0.0004us` looped for ever, even under `timeout 20ms` (issue 24)
    script = tmp_path / "zero.script"
    script.write_text("poll INT_STATUS_1 bit 7 == 1 timeout 20ms every 0.0004us\n")
    outcome = run_subprocess(["script", str(script), "-q", "--seed", "1"], limit_s=30)
    assert outcome.kind == "error", outcome


def test_the_classifier_calls_a_traceback_a_warning_and_two_errors_broken():
    # the suite's own check: if these passed, nothing above could fail
    assert classify(1, "Traceback (most recent call last):\n  ...\nValueError: x\n").broken
    assert classify(0, "x.py:3: RuntimeWarning: divide by zero\n").broken
    assert classify(2, "bmg160-emu a: error: one\nbmg160-emu a: error: two\n").broken
    assert classify(3, "bmg160-emu a: error: one\n").broken
    assert not classify(2, "usage: bmg160-emu a [-h]\nbmg160-emu a: error: one\n").broken
