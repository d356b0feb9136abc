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

from bmg160_emu import __version__, commands
from bmg160_emu.commands._common import CommandError  # the commands raise it; old name here
from bmg160_emu.commands._extras import missing_message

__all__ = ["CommandError", "build_parser", "main"]


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
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminate)  # commands may install their own
    try:
        return int(args.func(args) or 0)
    except CommandError as exc:
        print(f"bmg160-emu {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:  # an optional package: the extra that brings it
        message = missing_message(args.command, exc.name or "")
        if message is None:
            raise
        print(f"bmg160-emu {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        terminated = isinstance(exc, Terminated)
        print(f"bmg160-emu {args.command}: interrupted by "
              f"{'SIGTERM' if terminated else 'SIGINT'}", file=sys.stderr)
        return 143 if terminated else 130
    except BrokenPipeError:
        # The reader of our output went away (`bmg160-emu dump | head`): stop quietly, as
        # Unix tools do, and keep Python from complaining again when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    raise SystemExit(main())
