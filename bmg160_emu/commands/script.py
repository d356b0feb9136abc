"""``bmg160-emu script``: run a register script against an emulated chip."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from bmg160_emu.commands._chip_options import add_chip_options, chips_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_command_parser,
    add_progress_options,
    progress_for,
)

EPILOG = """\
examples:
  bmg160-emu script bringup.script --seed 7
  bmg160-emu script regression.script --range 500 --trace session.jsonl --quiet
  bmg160-emu script bringup.script --spi --seed 7       # the same session over SPI
  bmg160-emu script bmx055.script --device bmx055_gyro@0x68 --device bma2x2_accel@0x18

A script is one statement per line (docs/script-format.md):
  read CHIP_ID == 0x0F
  write BGW_SOFTRESET 0xB6
  advance 30ms
  write RANGE 0x02
  poll INT_STATUS_1 bit 7 timeout 20ms every 100us
  burst RATE_X_LSB 6

Mistakes in the script are all reported with line and column before anything runs
(exit 2). The first failed expectation stops the run with its line number and the
decoded difference (exit 1). Register accesses go through an emulated I2C bus 1, or
with --spi through SPI frames on a FakeSpiDev (spec 2.2).
"""


SCRIPT_BUS = 1  # the emulated bus a script's accesses go through


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "script",
        "run a register script (writes, expected reads, polls, time) against the chip",
        "Run a line-oriented register script against an emulated BMG160 and "
        "print a readable log; stop at the first failed expectation.",
        EPILOG,
    )
    parser.add_argument("file", type=Path, metavar="FILE", help="the register script")
    parser.add_argument(
        "--trace", type=Path, metavar="OUT.jsonl", default=None,
        help="record every bus transaction to a JSON Lines trace (docs/trace-format.md)",
    )
    parser.add_argument(
        "--spi", action="store_true",
        help="make the register accesses SPI frames on a FakeSpiDev instead of I2C transactions",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="print only failures")
    add_progress_options(parser)
    parser.add_argument(
        "--watch", action="store_true",
        help="make the session watchable live (bmg160-emu watch; best with --realtime)",
    )
    add_chip_options(parser, devices=True)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.commands._chip_options import close_trace, trace_writer_from_args
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.device.contract import RateSensor
    from bmg160_emu.session.script import ScriptRunner
    from bmg160_emu.session.script_language import (
        ScriptFailure,
        ScriptSyntaxError,
        parse_script,
        read_script,
    )

    try:
        statements = parse_script(read_script(args.file), str(args.file))
    except OSError as exc:
        raise CommandError(f"cannot read {args.file}: {exc.strerror}") from None
    except ScriptSyntaxError as exc:
        raise CommandError(
            f"{len(exc.errors)} error(s) in the script, nothing was run:",
            exc.lines,
        ) from None
    if args.trace is not None and getattr(args, "realtime", False):
        raise CommandError("--trace needs virtual time (a real-time session cannot be replayed)")
    if args.spi and len(set(args.addresses or [])) + len(args.devices or []) > 1:
        raise CommandError("--spi drives one chip (one chip select): give --address or "
                           "--device once")
    chips = chips_from_args(args, default_bus=SCRIPT_BUS)
    first = next((a for a, c in chips.items() if isinstance(c, RateSensor)), None)
    if first is None:
        raise CommandError("a script drives a gyro part: give --address or --device "
                           "PART@ADDRESS besides the stand-ins")
    chip = chips[first]
    chips = {first: chip, **chips}  # the script's default chip is the first gyro
    i2c_bus = I2CBus(SCRIPT_BUS, chips)
    bus: I2CBus | None = i2c_bus
    if args.spi:
        from bmg160_emu.bus.spi import FakeSpiDev
        from bmg160_emu.session.script import SpiRegisterPort

        spi = FakeSpiDev(chip)
        bus, port, log_ = None, SpiRegisterPort(spi), spi.log
    else:
        port, log_ = None, i2c_bus.log
    writer = None
    if args.trace is not None:
        writer = trace_writer_from_args(args)
        log_.sinks.append(writer)

    def log(line: str) -> None:
        if not args.quiet:
            print(line)

    runner = ScriptRunner(chip, log, str(args.file), port=port, bus=bus,
                          progress=progress_for(args, "script"))
    try:
        with contextlib.ExitStack() as watching:
            if args.watch:  # a live view (commands/watch.py); the script runs unchanged
                from bmg160_emu.watch.session import WatchError, watched

                try:
                    watching.enter_context(watched(chips, [log_], f"script {args.file}"))
                except (WatchError, OSError) as exc:
                    raise CommandError(f"--watch: {exc}") from None
            runner.run(statements)
    except ScriptFailure as exc:
        print(f"FAILED {exc}", file=sys.stderr)
        return 1
    finally:
        if writer is not None:
            close_trace(writer, args.trace)  # the transactions so far, also when stopped
    if not args.quiet:
        print(f"ok: {len(statements)} statements, t = {chip.time:.6f} s")
    return 0
