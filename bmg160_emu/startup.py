"""The command's first moments: SIGINT and SIGTERM held from the package's first line.

Run as the command (the console script, ``python -m bmg160_emu``), a ^C or a SIGTERM while
the package is still importing stops it with one line and the signal's exit status, never
a KeyboardInterrupt traceback out of the middle of an import (issues 24 and 35);
:mod:`bmg160_emu.cli` takes over when the command starts. Before this module runs, CPython
itself is starting (``site``, and with an editable install setuptools' import finder): a
signal then gets CPython's own answer, and nothing of ours has run or written anything
(docs/outputs.md gives the measured window).

A worker process that the command spawns (Dask's local cluster starts one per core through
multiprocessing) ignores SIGINT: a ^C at the terminal reaches the whole process group, and
the command alone decides what is kept and closes its workers; workers that died of the
^C themselves printed their own tracebacks and Dask's WARNINGs (issue 35).

Imports only what the interpreter needs for the handler, so that it is in place as early
as possible (``signal`` builds its enums on first import: 0.5 ms under ``python -m``,
where nothing has imported ``enum`` yet). A SIGINT while this module itself loads raises
KeyboardInterrupt before the handler exists; the package's ``__init__`` catches it and
calls :func:`interrupted_while_loading` (``tools/fuzz.py --signals`` had caught that
traceback: montecarlo-dask-json, seed 7800004, SIGINT at 0.020 s).
"""

from __future__ import annotations

import os
import signal
import sys

SIGNALS = (signal.SIGINT, signal.SIGTERM)
_NAMES: dict[int, str] = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}


def _main_file() -> str:
    return str(getattr(sys.modules.get("__main__"), "__file__", None) or "")


def _command_argv() -> bool:
    return bool(sys.argv) and sys.argv[0].endswith(("bmg160-emu", "bmg160_emu/__main__.py"))


# This process is the command: the console script (its file is __main__; a worker spawned
# from it gets its sys.argv, not its __main__) or python -m bmg160_emu.
AS_COMMAND = (_command_argv() and _main_file().endswith("bmg160-emu")) \
    or sys.orig_argv[1:3] == ["-m", "bmg160_emu"]
# A multiprocessing child of the command (spawned: its argv is the parent's, and the
# interpreter was started with --multiprocessing-fork)
AS_WORKER = not AS_COMMAND and _command_argv() and "--multiprocessing-fork" in sys.orig_argv


def stopped_while_starting(number: int, frame: object) -> None:
    """SIGINT or SIGTERM before a command runs: one line and the signal's exit status.

    As the command: ``os._exit``, not SystemExit: the handler may run inside a finaliser
    during an import, where an exception is printed and ignored (a traceback, and the command
    ran on), and before the command runs there is nothing to finish or clean up. Called in
    a program (tests call ``cli.main()``): SystemExit, which the program may catch."""
    name = _NAMES.get(number, f"signal {number}")
    sys.stderr.write(f"bmg160-emu: interrupted by {name} while starting; nothing written\n")
    if AS_COMMAND:
        sys.stderr.flush()
        os._exit(128 + number)
    raise SystemExit(128 + number)


def interrupted_while_loading() -> None:
    """A SIGINT that came while this module itself was loading (the package's first
    import, about 0.6 ms under ``python -m``, before :func:`hold_signals` could run) raised
    KeyboardInterrupt there: as the command, answered as :func:`stopped_while_starting`
    answers; otherwise (a program importing the package) the caller re-raises it."""
    if AS_COMMAND:
        stopped_while_starting(signal.SIGINT, None)


def hold_signals() -> None:
    """Install :func:`stopped_while_starting` (as the command) or ignore SIGINT (as its
    worker); a signal inherited as ignored (nohup, a background job) stays ignored."""
    if AS_COMMAND:
        for number in SIGNALS:
            if signal.getsignal(number) is not signal.SIG_IGN:
                signal.signal(number, stopped_while_starting)
    elif AS_WORKER:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
