"""Signals at seeded random moments for every command that writes a file (tests/_fuzz_signals.py
says the checks): no traceback, an exit status that says the signal, and every output
complete, absent, or marked partial and true as far as it goes. Four trials per command
here (about a minute in all); ``python tools/fuzz.py --signals`` runs a larger campaign."""

from __future__ import annotations

import numpy as np
import pytest
from _fuzz_signals import COMMANDS, _judge, campaign, plan, read_output

TRIALS = 4  # per command, one in each stratum of plan(): 14 commands, ~60 s here


@pytest.mark.parametrize("name", [c.name for c in COMMANDS if not c.campaign_only])
def test_a_signal_at_a_random_moment_leaves_every_output_honest(tmp_path, name):
    failures: list[str] = []

    def report(line: str) -> None:
        if line.startswith("  "):
            failures.append(line.strip())

    counts = campaign([name], TRIALS, 0, tmp_path, report)
    assert failures == [], "\n".join(failures)
    if name in counts:  # run-trace is skipped where umockdev cannot run
        assert counts[name].get("ok", 0) + counts[name].get("start-up", 0) == TRIALS


def test_the_plan_is_seeded_and_four_consecutive_trials_cover_every_phase_of_a_run():
    plans = [plan(seed, 2.0, 0.8) for seed in range(400)]
    assert plans == [plan(seed, 2.0, 0.8) for seed in range(400)]  # a seed reruns its trial
    for first in range(0, 400, 4):
        (_, early, e), (_, before, b), (_, writing, w), (_, after, a) = plans[first:first + 4]
        assert early < 0.15 and 0.15 <= before <= 0.8 and 0.8 <= after <= 2.2
        assert 0 <= writing <= 0.7 * 1.2 and (e, b, w, a) == (False, False, True, False)
    assert {n.name for n, _, _ in plans} == {"SIGINT", "SIGTERM"}


def test_the_judge_catches_an_unmarked_cut_output_and_a_marked_one_that_lies(tmp_path):
    # the oracle itself can fail: a trace cut short whose mark is lost (the end line
    # written on a cut session, by hand here) and a partial trace whose records differ
    from bmg160_emu.io.trace import TraceHeader, TraceWriter
    from bmg160_emu.traffic.transaction import Transaction

    def trace(path, records, complete):
        writer = TraceWriter(path, TraceHeader(seed=1))
        for t in records:
            writer(t)
        writer.close(complete=complete)

    session = [Transaction(0.001 * k, 1, 0x68, "read_byte_data", register=k, read=[k])
               for k in range(5)]
    whole_path = tmp_path / "whole.jsonl"
    trace(whole_path, session, complete=True)
    whole = read_output(whole_path)
    problems: list[str] = []
    assert _judge(whole_path, whole, problems, finished=True) == "complete" and problems == []
    cut = tmp_path / "cut.jsonl"
    trace(cut, session[:3], complete=True)  # the defect: an end line on a cut session
    assert _judge(cut, whole, problems, finished=False) == "complete"
    assert problems == ["cut.jsonl: not marked partial, but not the whole output"]
    problems.clear()
    trace(cut, session[:2] + session[3:4], complete=False)
    assert _judge(cut, whole, problems, finished=False) == "partial"
    assert problems == ["cut.jsonl: marked partial, but not the start of the whole output"]
    problems.clear()
    assert _judge(tmp_path / "absent.npy", np.zeros(3), problems, finished=True) == "absent"
    assert problems == ["absent.npy: absent after a run that says it finished"]
