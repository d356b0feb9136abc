"""The ``bmg160-emu`` command line: a thin dispatcher over the library.

Each sub-command lives in its own module under :mod:`bmg160_emu.commands` and exposes
``register(subparsers)``, which adds its parser with ``commands._common.add_command_parser``
and sets ``func`` (a callable taking the parsed arguments and returning an exit status); a
:class:`~bmg160_emu.commands._common.CommandError` is printed as one line, exit status 2. Commands are discovered, so adding one never
touches this file.
"""

from __future__ import annotations

import argparse
import atexit
import errno
import importlib
import os
import pkgutil
import re
import signal
import stat
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bmg160_emu import __version__, commands, startup
from bmg160_emu.commands._common import (  # what the commands raise: one line
    CommandError,
    add_command_parser,
)
from bmg160_emu.commands._extras import missing_message


def _stopped_while_exiting(number: int, frame: object) -> None:
    """A signal after the command returned: its outputs are finished (each is whole or
    absent, io.atomic); say so and exit now, with the signal's status (issue 35: a SIGTERM
    then used to end the process without a word)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is sys.stderr:
                stream.write(f"bmg160-emu {_EXITING[0]}: interrupted by "
                             f"{signal.Signals(number).name} while exiting; what it wrote is "
                             "whole (docs/outputs.md)\n")
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(128 + number)


_EXITING = ["?"]  # the command being run, for the line above


def _signals_ignored_at_the_end() -> None:
    """The last exit handler (registered first): from here the interpreter tears itself
    down, restoring the default handlers on the way (CPython's _PySignal_Fini), and a signal
    then ended the process without a word; ignored (a disposition the teardown keeps, in
    every thread), it is dropped, and the status is the command's."""
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, signal.SIG_IGN)


# Run as the command (the console script, python -m bmg160_emu), the process exits with the
# command; bmg160_emu.startup has held the signals since the package's first line.
# Imported by a program (tests call main() in-process), the handlers are restored at the end.
_AS_COMMAND = startup.AS_COMMAND
if _AS_COMMAND:
    atexit.register(_signals_ignored_at_the_end)
    # A file name is bytes on Linux, and one that is not UTF-8 reaches Python as lone
    # surrogates (PEP 383). Under a UTF-8 locale stdout refused them ("wrote k\udcff.yaml":
    # a UnicodeEncodeError after the files were written); written back as the bytes they
    # stand for, the name is the one the user typed, as ls prints it. (Under the C locale
    # Python does this itself; stderr already shows them as \udcff.)
    if getattr(sys.stdout, "errors", None) == "strict" and hasattr(sys.stdout, "reconfigure"):
        sys.stdout.reconfigure(errors="surrogateescape")

__all__ = ["build_parser", "main"]


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread as ^C is, so that every command stops the same way:
    partial outputs are removed (bmg160_emu.io.atomic), finished work is kept and said."""

    signal_name = "SIGTERM"  # read by code that reports how it was stopped (no cli import)


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


class CommandLine(argparse.ArgumentParser):
    """The top-level parser; ``command_parsers`` maps each command to its own parser, so
    that a command's mistakes are told with the command's usage (``demo --sed 3`` printed
    the top-level usage, issue 35)."""

    command_parsers: dict[str, argparse.ArgumentParser]


def build_parser() -> CommandLine:
    parser = CommandLine(
        prog="bmg160-emu",
        description="Emulate the Bosch BMG160 gyroscope at register level.",
        epilog="bmg160-emu help COMMAND (or bmg160-emu COMMAND --help) describes a command.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
    helper = add_command_parser(
        sub, "help", "describe bmg160-emu or one of its commands",
        "Describe bmg160-emu, or the command named.",
        "examples:\n  bmg160-emu help\n  bmg160-emu help identify")
    helper.add_argument("topic", nargs="?", metavar="COMMAND", help="a command (default: all)")
    helper.set_defaults(func=lambda args: _help(parser, args.topic))
    parser.command_parsers = dict(sub.choices)
    return parser


def _help(parser: CommandLine, topic: str | None) -> int:
    """``bmg160-emu help [COMMAND]``: the help of the program or of one command."""
    if topic is None:
        parser.print_help()
        return 0
    command = parser.command_parsers.get(topic)
    if command is None:
        names = ", ".join(sorted(parser.command_parsers))
        parser.command_parsers["help"].error(f"no command {topic!r}; the commands: {names}")
    command.print_help()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = {}
    if in_main_thread:  # restored at the end unless this process is the command
        previous = {n: signal.signal(n, startup.stopped_while_starting)
                    for n in (signal.SIGINT, signal.SIGTERM)
                    if signal.getsignal(n) is not signal.SIG_IGN}
    command = "?"
    from bmg160_emu.io.atomic import outputs_so_far

    before = outputs_so_far()
    try:
        parser = build_parser()
        args, extra = parser.parse_known_args(argv)
        command = _EXITING[0] = args.command
        if extra:  # told with the command's own usage, not the program's
            parser.command_parsers.get(command, parser).error(
                f"unrecognized arguments: {' '.join(extra)}")
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        if _AS_COMMAND:
            # numpy turns an exception raised inside its C-extension import (the
            # KeyboardInterrupt of a ^C) into an ImportError traceback, exit 1: imported while
            # a signal still means "nothing written, exit now" (tests/_fuzz_signals.py,
            # record-npz seed 0, SIGTERM at 0.114 s); every writing command needs it anyway
            import numpy  # noqa: F401
        try:
            # from here a signal stops the command, which keeps what it can
            if signal.SIGINT in previous:
                signal.signal(signal.SIGINT, signal.default_int_handler)
            if signal.SIGTERM in previous:  # commands may install their own
                signal.signal(signal.SIGTERM, _terminate)
            return int(args.func(args) or 0)
        finally:
            for number in previous:
                signal.signal(number, _stopped_while_exiting if _AS_COMMAND
                              else _restorable(previous[number]))
    except CommandError as exc:
        print(_one_line(f"bmg160-emu {command}: error: {exc}"), file=sys.stderr)
        for line in exc.details:
            print(_one_line(line), file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:  # an optional package: the extra that brings it
        message = missing_message(args.command, exc.name or "")
        if message is None:
            raise
        print(_one_line(f"bmg160-emu {args.command}: error: {message}"), file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        name = getattr(exc, "signal_name", "SIGINT")
        kept = getattr(exc, "kept", None) or _what_was_kept(before)
        print(_one_line(f"bmg160-emu {command}: interrupted by {name}; {kept}"),
              file=sys.stderr)
        return 143 if name == "SIGTERM" else 130
    except BrokenPipeError:
        # The reader of our output went away (`bmg160-emu dump | head`): stop quietly, as
        # Unix tools do, and keep Python from complaining again when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as exc:
        # a file the user named that the system refuses (a name too long, a loop of links, a
        # folder where a file was meant): one line naming it, wherever the command met it
        # (issue 35: path options were checked one by one, and a 300-character name slipped
        # through four of them). An OSError without a file name is a defect: its traceback.
        if exc.filename is None:
            if not _stdout_refused(exc):
                raise
            print(_one_line(f"bmg160-emu {command}: error: cannot write standard output: "
                            f"{exc.strerror or exc}"), file=sys.stderr)
            return 2
        from bmg160_emu.io.atomic import name_problem, shown_path

        why = name_problem(exc.filename) or exc.strerror or type(exc).__name__
        print(_one_line(f"bmg160-emu {command}: error: cannot use {shown_path(exc.filename)}: "
                        f"{why}"), file=sys.stderr)
        return 2
    finally:
        if not _AS_COMMAND:
            for number, handler in previous.items():
                signal.signal(number, _restorable(handler))


def _stdout_refused(exc: OSError) -> bool:
    """Whether ``exc`` is standard output refusing what the command printed: no room where
    it goes (``> /dev/full``, a full disk). A write to stdout fails without a file name, so
    the error is matched to stdout by its errno and stdout's own state. Stdout then goes to
    /dev/null, so that Python's flush at exit does not fail once more (as after a
    BrokenPipeError)."""
    if exc.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        return False
    try:
        fd = sys.stdout.fileno()
        st = os.fstat(fd)
        if stat.S_ISCHR(st.st_mode):  # Linux's /dev/full is character device 1, 7
            full = (os.major(st.st_rdev), os.minor(st.st_rdev)) == (1, 7)
        else:
            room = os.fstatvfs(fd)
            full = room.f_bavail == 0 or room.f_bfree == 0 or exc.errno == errno.EFBIG
    except (OSError, ValueError, AttributeError):  # no file behind stdout (a test's StringIO)
        return False
    if full:
        os.dup2(os.open(os.devnull, os.O_WRONLY), fd)
    return full


_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f]")


def _one_line(text: str) -> str:
    """An error for stderr as one line: a control character a file name may hold (a newline,
    a CR that would send the terminal back over the line) shown as \\xNN."""
    return _CONTROL.sub(lambda m: f"\\x{ord(m[0]):02x}", text)


def _what_was_kept(before: tuple[list[Path], list[Path]]) -> str:
    """What a stopped command leaves, from io.atomic's record of this command's outputs:
    never "removed" alone when some were written whole (issue 35)."""
    from bmg160_emu.io.atomic import outputs_so_far

    written, discarded = (after[len(then):] for after, then in zip(outputs_so_far(), before))
    done = [str(p) for p in dict.fromkeys(written)]
    cut = [str(p) for p in dict.fromkeys(discarded) if str(p) not in done]
    if not done and not cut:
        return "nothing written"
    said = []
    if done:
        said.append(f"{', '.join(done)} written whole")
    if cut:
        said.append(f"unfinished {', '.join(cut)} removed (docs/outputs.md)")
    return "; ".join(said)


def _restorable(handler: Any) -> Any:
    return signal.SIG_DFL if handler is None else handler


if __name__ == "__main__":
    raise SystemExit(main())
