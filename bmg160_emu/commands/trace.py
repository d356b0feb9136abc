"""``bmg160-emu trace``: decode a transaction trace for a person, or replay it."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from bmg160_emu.commands._common import Subparsers, add_command_parser
from bmg160_emu.io.trace import TraceHeader

EPILOG = """\
examples:
  bmg160-emu script bringup.script --seed 7 --trace session.jsonl
  bmg160-emu trace session.jsonl
  bmg160-emu trace session.jsonl --replay

Decoded lines read like "write 0x0F RANGE <- 0x02 (+-500 deg/s)" and
"burst read 0x02..0x07 -> x=-12 y=3 z=40". --replay rebuilds the chips from the trace's
header (same seed, same settings), replays every transaction at its recorded time and
reports the first one whose result differs (exit 1), or that none does (exit 0).
Faults injected during the session (fault:<kind> lines, failed transactions) are acted
again on the replay chips at the same points.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "trace",
        "decode a JSON Lines transaction trace, or replay it against a fresh chip",
        "Print a transaction trace (docs/trace-format.md) decoded register by "
        "register, or replay it against fresh chips and report the first divergence.",
        EPILOG,
    )
    parser.add_argument("file", type=Path, metavar="FILE", help="trace file (.jsonl)")
    parser.add_argument("--replay", action="store_true", help="replay and compare instead of printing")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.device.config import ChipConfig
    from bmg160_emu.device.parts import part_table
    from bmg160_emu.device.standin import StandinConfig
    from bmg160_emu.io.trace import TraceFormatError, read_trace
    from bmg160_emu.session.decode import describe_transaction
    from bmg160_emu.session.trace_replay import replay_trace

    try:
        header, records = read_trace(args.file)
    except OSError as exc:
        raise CommandError(f"cannot read {args.file}: {exc.strerror}") from None
    except (TraceFormatError, UnicodeDecodeError) as exc:
        raise CommandError(str(exc)) from None
    partial = header.get("_partial")
    if partial:  # replayed or decoded all the same, and said (docs/outputs.md)
        print(f"bmg160-emu trace: warning: {args.file} is partial ({partial}); "
              f"{'replaying' if args.replay else 'decoding'} the {len(records)} transactions "
              "it holds", file=sys.stderr)
    if not args.replay:
        try:
            configs = TraceHeader.from_dict(header).configs()
        except (TraceFormatError, ValueError) as exc:
            raise CommandError(f"{args.file}: {exc}") from None
        standins = {c.address: c.spec for c in configs if isinstance(c, StandinConfig)}
        parts: dict[int, Any] = {c.address: part_table(c.part).registers
                                 for c in configs if isinstance(c, ChipConfig)}
        for record in records:
            try:
                text = describe_transaction(record, standins, parts)
            except (ValueError, TypeError, KeyError) as exc:
                raise CommandError(f"{args.file}:{record['_line']}: cannot decode: {exc}") from None
            try:
                print(text)
            except BrokenPipeError:  # the reader (head, less) has gone: stop quietly
                sys.stdout = open(os.devnull, "w")  # noqa: SIM115
                return 0
        return 0
    try:
        result = replay_trace(header, records)
    except TraceFormatError as exc:
        raise CommandError(f"{args.file}: {exc}") from None
    except (ValueError, TypeError) as exc:
        raise CommandError(f"{args.file}: cannot replay: {exc}") from None
    faults = ""
    if result.faults_reapplied:
        faults = f" ({result.faults_reapplied} injected fault(s) re-applied)"
    if result.faults_skipped:
        print(f"note: the session had {len(result.faults_skipped)} injected fault(s) that the "
              "replay cannot act again (entries without parameters); reads after them may differ:",
              file=sys.stderr)
        for text in result.faults_skipped:
            print(f"  {args.file}:{text}", file=sys.stderr)
    if result.ok:
        cut = " (a partial trace: the session's end is missing)" if partial else ""
        print(f"no divergence: {result.transactions} transactions replayed{faults}{cut}")
        return 0
    print(f"divergence at {args.file}:{result.divergence}", file=sys.stderr)
    return 1

