"""``bmg160-emu watch``: a live terminal view of a running session, attached by its socket."""

from __future__ import annotations

import argparse
from pathlib import Path

from bmg160_emu.commands._common import Subparsers, add_command_parser

EPILOG = """\
examples:
  python3 examples/watch_session.py                       # a two-minute session to watch
  bmg160-emu script bringup.script --realtime --watch     # a short one (0.1 s)
  bmg160-emu watch                                        # attach to the newest session
  bmg160-emu watch --list
  bmg160-emu watch --socket /run/user/1000/bmg160-emu/4242-0.sock

A session started with --watch (run, script) serves snapshots on a Unix socket in a
directory only you can enter ($XDG_RUNTIME_DIR/bmg160-emu, else /tmp/bmg160-emu-UID, mode
0700); nothing listens on a network port. The view shows the 64 registers (changes
highlighted and decoded), the three rates as sparklines, the FIFO level, INT1/INT2,
transactions per second and the last transactions. q (or Ctrl-C) leaves the view; the
session goes on. Needs the rich package (pip install 'bmg160-emu[watch]').
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "watch",
        "live terminal view of a running session (registers, rates, FIFO, interrupts)",
        "Attach to a session started with --watch and show its chip live: registers with "
        "changes highlighted, rates, FIFO level, interrupt lines and the bus traffic.",
        EPILOG,
    )
    parser.add_argument(
        "--socket", type=Path, default=None, metavar="PATH",
        help="the session's socket (default: the newest live session)",
    )  # fmt: skip
    parser.add_argument("--list", action="store_true", help="list the live sessions and exit")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.watch.session import WatchError, live_sockets

    try:
        if args.list:
            for path in live_sockets():
                print(path)
            return 0
        path = args.socket
        if path is None:
            sockets = live_sockets()
            if not sockets:
                raise CommandError(
                    "no live session to watch: start one with --watch "
                    "(bmg160-emu script FILE --realtime --watch, bmg160-emu run --watch -- PROGRAM)"
                )
            path = sockets[0]
        try:
            from bmg160_emu.watch.view import run_viewer
        except ModuleNotFoundError as exc:
            from bmg160_emu.commands._extras import missing_message

            message = missing_message("watch", exc.name or "")
            if message is None:
                raise
            raise CommandError(message) from None
        return run_viewer(path)
    except WatchError as exc:
        raise CommandError(str(exc)) from None
