"""A long job's progress on stderr (bmg160_emu.progress, issue 35): the estimate said before
the bulk of the work when it is over a minute, a redrawn line on a terminal, a line per tenth
in a log, nothing for a short job. Driven by a fake clock: what is asserted is what the
report says for given times, never how fast this host is."""

from __future__ import annotations

import io

import pytest

from bmg160_emu.progress import Progress, spoken_duration


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _run(progress: Progress, clock: Clock, total: int, seconds_each: float) -> None:
    with progress.stage(total, "runs") as update:
        for done in range(1, total + 1):
            clock.now += seconds_each
            update(done)


def test_a_long_job_in_a_log_says_its_estimate_then_a_line_per_tenth():
    clock, out = Clock(), io.StringIO()
    _run(Progress("bmg160-emu montecarlo", stream=out, terminal=False, clock=clock), clock,
         100, 1.5)  # 150 s in all
    lines = out.getvalue().splitlines()
    assert lines[0] == ("bmg160-emu montecarlo: about 2.5 min for 100 runs, from the first 2 s "
                        "on this machine; ^C stops it and keeps what is finished")
    # the tenths 1..9 (the end is the command's own line)
    assert [line.split(" (")[0] for line in lines[1:]] == [
        f"bmg160-emu montecarlo: {k}0/100 runs" for k in range(1, 10)]
    assert lines[5] == "bmg160-emu montecarlo: 50/100 runs (50 %), 75 s so far, about 75 s left"


def test_a_short_job_in_a_log_writes_nothing():
    clock, out = Clock(), io.StringIO()
    _run(Progress("x", stream=out, terminal=False, clock=clock), clock, 100, 0.5)  # 50 s
    assert out.getvalue() == ""


def test_the_estimate_waits_for_a_second_of_work_and_is_said_once():
    clock, out = Clock(), io.StringIO()
    progress = Progress("x", stream=out, terminal=False, clock=clock)
    with progress.stage(1000, "fits") as update:
        clock.now = 0.5
        update(10)  # half a second: too little to judge
        assert out.getvalue() == ""
        clock.now = 1.0
        update(20)  # 0.05 s a fit: 50 s in all, under a minute: not said
        clock.now = 20.0
        update(21)  # slower now, but the estimate is made once
    assert "about" not in out.getvalue().split("\n")[0]


def test_on_a_terminal_one_line_is_redrawn_with_the_time_left():
    clock, out = Clock(), io.StringIO()
    _run(Progress("x", stream=out, terminal=True, clock=clock), clock, 16, 0.25)  # 4 s
    text = out.getvalue()
    assert "\n" not in text.rstrip("\n")  # one line, redrawn with \r
    assert text.count("\r") == 13 + 1  # at 1 s, 1.25 s, ... 4 s (every 0.25 s), and the end
    assert "x: 8/16 runs (50 %), 2 s so far, about 2 s left" in text
    assert text.endswith("x: 16/16 runs (100 %), 4 s so far\x1b[K\n")


def test_no_progress_on_a_terminal_still_says_a_long_estimate():
    clock, out = Clock(), io.StringIO()
    _run(Progress("x", stream=out, terminal=True, enabled=False, clock=clock), clock, 100, 2.0)
    assert out.getvalue().count("\n") == 1 and out.getvalue().startswith("x: about 3.3 min")


def test_asked_for_off_a_terminal_a_line_comes_with_the_first_unit():
    clock, out = Clock(), io.StringIO()
    progress = Progress("x", stream=out, terminal=False, enabled=True, clock=clock)
    with progress.stage(100_000, "runs") as update:
        clock.now = 0.05
        update(1)
    assert out.getvalue().startswith("x: 1/100,000 runs (0 %)")


def test_a_broken_stderr_does_not_stop_the_work():
    class Broken(io.StringIO):
        def write(self, text):
            raise BrokenPipeError

    clock = Clock()
    _run(Progress("x", stream=Broken(), terminal=True, clock=clock), clock, 10, 10.0)


@pytest.mark.parametrize(("seconds", "said"), [
    (0.4, "0 s"), (45, "45 s"), (150, "2.5 min"), (600, "10 min"), (3.6 * 3600, "3.6 h"), (20 * 3600, "20 h"),
    (3 * 86400, "3.0 days"), (15 * 86400, "15 days"), (float("inf"), "an unknown time")])
def test_durations_are_said_as_a_person_says_them(seconds, said):
    assert spoken_duration(seconds) == said


def test_an_advance_reported_in_steps_gives_the_same_session():
    # a script's long advance goes a simulated minute at a time when its progress is shown
    # (issue 35: `advance 720h` ran for half an hour without a sign): the same samples,
    # registers and time as one advance, the chip being chunk invariant
    from bmg160_emu import BMG160
    from bmg160_emu.session.script import run_script

    text = ("write BW 0x01\nadvance 125.3s\nburst RATE_X_LSB 6\nread FIFO_STATUS\n"
            "advance 61s\nburst RATE_X_LSB 6\n")
    sessions = []
    for progress in (None, Progress("t", stream=io.StringIO(), terminal=False)):
        lines: list[str] = []
        chip = BMG160(seed=4)
        run_script(text, chip, lines.append, progress=progress)
        sessions.append((lines, chip.time))
    assert sessions[0] == sessions[1]


def test_a_long_advance_tells_its_simulated_minutes():
    from bmg160_emu import BMG160
    from bmg160_emu.session.script import run_script

    out = io.StringIO()
    run_script("advance 150s\n", BMG160(seed=1), lambda line: None,
               progress=Progress("bmg160-emu script", stream=out, terminal=False, enabled=True))
    assert "bmg160-emu script: 1/3 simulated minutes (33 %)" in out.getvalue()


def test_a_command_s_own_lines_print_above_the_progress_line():
    # demo's table on stdout and the progress line on stderr share the terminal: each row
    # takes the progress line off, prints, and puts it back under it
    clock, err, rows = Clock(), io.StringIO(), []
    progress = Progress("x", stream=err, terminal=True, clock=clock)
    with progress.beside(4, "samples", rows.append) as (update, say):
        for k in range(1, 5):
            clock.now += 1.0
            say(f"row {k}")
            update(k)
    assert rows == ["row 1", "row 2", "row 3", "row 4"]
    text = err.getvalue()
    assert text.count("\r\x1b[K") == 3  # cleared before rows 2, 3, 4 (drawn after row 1)
    assert text.endswith("x: 4/4 samples (100 %), 4 s so far\x1b[K\n")
