"""``bmg160-emu diff``: two register dumps side by side, with the fields that differ decoded."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bmg160_emu.commands._common import Subparsers, add_command_parser

EPILOG = """\
examples:
  bmg160-emu diff before.dump after.dump
  bmg160-emu diff --all reset.json configured.txt

Each file may be in any dump format (i2cdump, table or json; detected from the text).
Exit status: 0 when the dumps are equal, 1 when they differ, 2 on a bad file.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "diff",
        "compare two register dumps field by field",
        "Show the registers two dumps disagree on, side by side, with every "
        "field that differs decoded by name.",
        EPILOG,
    )
    parser.add_argument("a", type=Path, metavar="A", help="first dump")
    parser.add_argument("b", type=Path, metavar="B", help="second dump")
    parser.add_argument("--all", action="store_true", help="list every register, marking differences")
    parser.set_defaults(func=run)


def _load(path: Path):
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.io.dump import DumpFormatError, parse_dump
    from bmg160_emu.io.errors import read_text

    try:
        return parse_dump(read_text(path, DumpFormatError), str(path))
    except OSError as exc:
        raise CommandError(f"cannot read {path}: {exc.strerror}") from None
    except DumpFormatError as exc:
        raise CommandError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.session.decode import diff_dumps, format_diff

    a, b = _load(args.a), _load(args.b)
    sys.stdout.write(format_diff(a, b, args.a.name, args.b.name, show_all=args.all))
    return 1 if diff_dumps(a, b) else 0
