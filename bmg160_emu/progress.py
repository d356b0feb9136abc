"""How far a long job has got and how long it has left, on stderr (issue 35).

A job that runs for minutes or hours (a million Monte Carlo runs, 10,000 bootstrap fits, a
script's ``advance 720h``, a 30-day firmware capture) must not look hung. :class:`Progress`
gives every such job the same three things:

- **an estimate before the bulk of the work**: once the first units are done (at least one,
  and a second of work), the time they took gives the whole job's; when it is over a minute,
  one line says so (``about 3.6 h for 30,000 bootstrap fits, from the first 12 s on this
  machine``), on a terminal and in a log alike, so that a user can stop a job that is not
  worth its hours;
- **on a terminal**, one line redrawn at most four times a second: done, total, percent and
  the time left;
- **without a terminal** (a log, CI), a line per tenth of a job that was announced as long,
  nothing for a short one: a log keeps what a person reads later, not a stream of redraws.
  Asked for there (``--progress``), a line when the first unit is done, at each tenth and
  at least every 30 s.

Jobs with several stages (read, fit, bootstrap, figures) open one stage after another; each
stage is its own line. The clock is a parameter, so tests drive it in virtual time.
Nothing here needs an optional package (tqdm is an extra, and the base install reports
progress too).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Protocol

ANNOUNCE_OVER_S = 60.0  # an estimate longer than this is said before the bulk of the work
MEASURE_S = 1.0  # the first units must have taken this long before their rate counts
REDRAW_S = 0.25  # a terminal line is redrawn at most this often
LOG_EVERY_S = 30.0  # asked for off a terminal (--progress): a line at least this often
SHOW_AFTER_S = 1.0  # a terminal line appears only for a stage that lasts longer than this

Update = Callable[[int], None]  # done so far (0..total)


class Stream(Protocol):
    """Where the lines go (stderr, or any object with ``write`` and ``flush``)."""

    def write(self, text: str, /) -> int: ...

    def flush(self) -> None: ...


def spoken_duration(seconds: float) -> str:
    """A time span as a person says it: ``45 s``, ``2.5 min``, ``12 min``, ``3.6 h``, ``15 days``."""
    if not math.isfinite(seconds):
        return "an unknown time"
    if seconds < 90:
        return f"{max(seconds, 0.0):.0f} s"
    if seconds < 600:
        return f"{seconds / 60:.1f} min"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    if seconds < 48 * 3600:
        hours = seconds / 3600
        return f"{hours:.1f} h" if hours < 10 else f"{hours:.0f} h"
    return f"{seconds / 86400:.0f} days" if seconds >= 10 * 86400 else f"{seconds / 86400:.1f} days"


class Progress:
    """The progress of one command's long work on ``stream`` (default stderr).

    ``label`` starts every line (``bmg160-emu montecarlo``); ``on_stop`` says what a ^C
    keeps, after a long estimate. ``terminal`` None asks the
    stream (``isatty()``); ``enabled`` False draws nothing on a terminal (``--no-progress``)
    but still says a long estimate, True draws even where the stream is not a terminal
    (``--progress``)."""

    def __init__(self, label: str, *, stream: Stream | None = None, terminal: bool | None = None,
                 enabled: bool | None = None, clock: Callable[[], float] = time.monotonic,
                 on_stop: str = "^C stops it and keeps what is finished") -> None:
        self.label = label
        self.on_stop = on_stop  # what a stop keeps, said with a long estimate
        self.stream: Stream = stream if stream is not None else sys.stderr
        if terminal is None:
            isatty = getattr(self.stream, "isatty", None)
            try:
                terminal = bool(isatty and isatty())
            except (ValueError, OSError):  # a closed stream
                terminal = False
        self.draw = terminal if enabled is None else enabled
        self.quiet = enabled is False  # only a long estimate is said
        self.terminal = terminal
        self.clock = clock

    @contextmanager
    def stage(self, total: int, unit: str = "", what: str = "") -> Iterator[Update]:
        """One stage of ``total`` units (runs, fits, samples): yields ``update(done)``."""
        stage = self.start(total, unit, what)
        try:
            yield stage.update
        finally:
            stage.close()

    @contextmanager
    def beside(self, total: int, unit: str, print_line: Callable[[str], None]
               ) -> Iterator[tuple[Update, Callable[[str], None]]]:
        """A stage whose command prints lines of its own to the same terminal (demo's
        table on stdout): yields ``update(done)`` and ``say(line)``, which takes the
        progress line off the terminal, prints the command's line and puts the progress
        line back under it, so that neither garbles the other."""
        stage = self.start(total, unit)

        def say(line: str) -> None:
            drawn = stage.drawn_at >= 0 and not stage.closed
            if drawn:
                self._write("\r\x1b[K")
            print_line(line)
            if drawn:
                self._write(stage._line(self.clock() - stage.started))

        try:
            yield stage.update, say
        finally:
            stage.close()

    def start(self, total: int, unit: str = "", what: str = "") -> _Stage:
        """A stage without a ``with`` block: ``.update(done)``; it ends its terminal line
        when ``done`` reaches ``total`` (``.close()`` ends it earlier)."""
        return _Stage(self, max(int(total), 0), unit, what)

    def say(self, text: str) -> None:
        """One line of its own (a stage that has no count)."""
        self._write(f"{self.label}: {text}\n")

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # a closed or broken stderr must not stop the work
            pass


class _Stage:
    def __init__(self, owner: Progress, total: int, unit: str, what: str) -> None:
        self.owner = owner
        self.total = total
        self.unit = unit
        self.what = what or (f"{total:,} {unit}".strip())
        self.started = owner.clock()
        self.done = 0
        self.drawn_at = -1.0  # when the terminal line was last drawn (-1: never)
        self.announced = False
        self.judged = False  # the estimate has been made (said or not)
        self.next_tenth = 1
        self.logged_at = -1.0  # when the last log line was written (-1: never)
        self.closed = False

    def update(self, done: int) -> None:
        if self.closed:
            return
        self.done = min(max(int(done), 0), self.total) if self.total else int(done)
        now = self.owner.clock()
        elapsed = now - self.started
        if not self.judged and self.done >= 1 and elapsed >= MEASURE_S:
            self.judged = True
            whole = elapsed / self.done * self.total
            if whole > ANNOUNCE_OVER_S and self.done < self.total:
                self.announced = True
                self.owner._write(
                    f"{self.owner.label}: about {spoken_duration(whole)} for {self.what}, "
                    f"from the first {spoken_duration(elapsed)} on this machine; "
                    f"{self.owner.on_stop}\n")
        if self.owner.draw and self.owner.terminal:
            if elapsed >= SHOW_AFTER_S and (self.drawn_at < 0 or now - self.drawn_at >= REDRAW_S):
                self.drawn_at = now
                self.owner._write("\r" + self._line(elapsed) + "\x1b[K")
        elif not self.owner.quiet and (self.announced or self.owner.draw):
            line = False
            while self.total and self.done * 10 >= self.next_tenth * self.total \
                    and self.next_tenth <= 10:
                line = line or self.next_tenth < 10  # the end: the command says it
                self.next_tenth += 1
            if self.owner.draw and self.done and self.done < self.total and (
                    self.logged_at < 0 or now - self.logged_at >= LOG_EVERY_S):
                line = True
            if line:
                self.logged_at = now
                self.owner._write(self._line(elapsed) + "\n")
        if self.total and self.done >= self.total:
            self.close()

    def _line(self, elapsed: float) -> str:
        parts = [f"{self.owner.label}: {self.what}"]
        if self.total:
            parts = [f"{self.owner.label}: {self.done:,}/{self.total:,} {self.unit}".rstrip()
                     + f" ({100.0 * self.done / self.total:.0f} %)"]
        parts.append(f"{spoken_duration(elapsed)} so far")
        if self.done and self.total and self.done < self.total:
            left = elapsed / self.done * (self.total - self.done)
            parts.append(f"about {spoken_duration(left)} left")
        return ", ".join(parts)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self.drawn_at >= 0:  # the terminal line: leave its last state, end the line
            self.owner._write("\r" + self._line(self.owner.clock() - self.started)
                              + "\x1b[K\n")
