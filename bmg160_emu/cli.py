"""The ``bmg160-emu`` command line: a thin dispatcher over the library.

Each sub-command lives in its own module under :mod:`bmg160_emu.commands` and exposes
``register(subparsers)``, which adds its parser with ``commands._common.add_command_parser``
and sets ``func`` (a callable taking the parsed arguments and returning an exit status); a
:class:`~bmg160_emu.commands._common.CommandError` is printed as one line, exit status 2. Commands are discovered, so adding one never
touches this file.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import signal
import sys
import threading
from collections.abc import Sequence
from typing import Any

from bmg160_emu import __version__, commands
from bmg160_emu.commands._common import CommandError  # what the commands raise: one line
from bmg160_emu.commands._extras import missing_message


def _stopped_while_starting(number: int, frame: object) -> None:
    """SIGINT or SIGTERM before a command runs: one line and the signal's exit status, never
    a KeyboardInterrupt traceback from the middle of an import (issue 24)."""
    name = signal.Signals(number).name
    sys.stderr.write(f"bmg160-emu: interrupted by {name} while starting; nothing written\n")
    if _AS_COMMAND:  # nothing to clean up yet, and no finaliser can swallow it (__init__.py)
        sys.stderr.flush()
        os._exit(128 + number)
    raise SystemExit(128 + number)


def _stopped_while_exiting(number: int, frame: object) -> None:
    """A signal after the command returned: its outputs are finished; exit now, as it says."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(128 + number)


# Run as the command (the console script, python -m bmg160_emu), the process exits with the
# command; bmg160_emu/__init__.py has held the signals since the package's first line.
# Imported by a program (tests call main() in-process), the handlers are restored at the end.
_AS_COMMAND = sys.argv[0].endswith(("bmg160-emu", "bmg160_emu/__main__.py"))

__all__ = ["build_parser", "main"]


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread as ^C is, so that every command stops the same way:
    partial outputs are removed (bmg160_emu.io.atomic), finished work is kept and said."""

    signal_name = "SIGTERM"  # read by code that reports how it was stopped (no cli import)


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bmg160-emu",
        description="Emulate the Bosch BMG160 gyroscope at register level.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = {}
    if in_main_thread:  # restored at the end unless this process is the command
        previous = {n: signal.signal(n, _stopped_while_starting)
                    for n in (signal.SIGINT, signal.SIGTERM)
                    if signal.getsignal(n) is not signal.SIG_IGN}
    command = "?"
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        command = args.command
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
        print(f"bmg160-emu {command}: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:  # an optional package: the extra that brings it
        message = missing_message(args.command, exc.name or "")
        if message is None:
            raise
        print(f"bmg160-emu {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        name = getattr(exc, "signal_name", "SIGINT")
        kept = getattr(exc, "kept", None) or "unfinished outputs removed (docs/outputs.md)"
        print(f"bmg160-emu {command}: interrupted by {name}; {kept}", file=sys.stderr)
        return 143 if name == "SIGTERM" else 130
    except BrokenPipeError:
        # The reader of our output went away (`bmg160-emu dump | head`): stop quietly, as
        # Unix tools do, and keep Python from complaining again when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    finally:
        if not _AS_COMMAND:
            for number, handler in previous.items():
                signal.signal(number, _restorable(handler))


def _restorable(handler: Any) -> Any:
    return signal.SIG_DFL if handler is None else handler


if __name__ == "__main__":
    raise SystemExit(main())
