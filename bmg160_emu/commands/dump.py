"""``bmg160-emu dump``: the chip's 64 registers as i2cdump prints them, decoded, or as JSON."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bmg160_emu.commands._chip_options import add_chip_options, chips_from_args
from bmg160_emu.commands._common import Subparsers, add_command_parser, run_script_file


def _address(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an I2C address: {text!r}") from None

EPILOG = """\
examples:
  bmg160-emu dump                                   # decoded table after power-up
  bmg160-emu dump --format i2cdump > bmg160.dump    # sudo i2c-stub-from-dump 0x68 bmg160.dump
  bmg160-emu dump --range 500 --after bringup.script --format json
  bmg160-emu dump --address 0x68 --address 0x69 --format i2cdump
  bmg160-emu dump --address 0x68 --address 0x69 --after two.script --chip 0x69

  bmg160-emu dump --device bmm150@0x10 --chip 0x10 > bmm150.dump   # a stand-in: 0x00..0xff

The i2cdump format is byte for byte what `i2cdump -y -r 0x00-0x3f BUS 0x68 b` prints; a
stand-in (--device) is dumped whole, as `i2cdump -y BUS ADDRESS b` prints it, whatever
--format says (json cannot hold one).
With several --address options every chip is dumped, one block per address (json: a
list); --chip dumps one of them (for i2c-stub-from-dump, which loads one chip per file).
The dump reads no register through the bus: it has no read side effects (FIFO, shadowing).
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "dump",
        "print the chip's 64 registers (i2cdump, decoded table or JSON)",
        "Print registers 0x00..0x3F of an emulated BMG160, optionally after "
        "running a register script, in i2cdump's layout, as a decoded table, or as JSON.",
        EPILOG,
    )
    parser.add_argument(
        "--format", choices=("i2cdump", "table", "json"), default="table",
        help="output format (default: table)",
    )
    parser.add_argument(
        "--after", type=Path, metavar="SCRIPT", default=None,
        help="run this register script first (its log goes to stderr)",
    )
    parser.add_argument(
        "--chip", type=_address, metavar="ADDRESS", default=None,
        help="dump only the chip at this address (one of --address; default: every chip)",
    )
    parser.add_argument("-o", "--output", type=Path, default=None, metavar="FILE",
                        help="write to FILE")
    add_chip_options(parser, devices=True)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.device.contract import RateSensor
    from bmg160_emu.io.dump import DUMP_TITLE, RegisterDump, format_dumps, format_i2cdump

    chips = chips_from_args(args)
    if args.chip is not None and args.chip not in chips:
        emulated = ", ".join(f"0x{a:02x}" for a in chips)
        raise CommandError(f"--chip 0x{args.chip:02x} is not an emulated chip ({emulated}); "
                           "add it with --address or --device")
    chosen = {a: c for a, c in chips.items() if args.chip is None or a == args.chip}
    standins = {a: c for a, c in chosen.items() if not isinstance(c, RateSensor)}
    if standins and args.format == "json":
        raise CommandError("--format json holds BMG160-family registers; a stand-in dumps as "
                           "i2cdump only (give --format i2cdump, or --chip for a gyro)")
    if args.after is not None:

        def log(line: str) -> None:
            print(line, file=sys.stderr)

        if run_script_file(args.after, chips, log, "script failed: "):
            return 1
    dumps = []
    for address, each in chosen.items():
        if address in standins:
            continue
        dump = RegisterDump.from_chip(each)
        dump.metadata["sensitivity"] = getattr(args, "sensitivity", None)
        dumps.append(dump)
    blocks = [format_dumps(dumps, args.format)] if dumps else []
    if len(dumps) == 1 and standins and args.format == "i2cdump":  # title it, as for several
        only = dumps[0]
        blocks[0] = f"{DUMP_TITLE}  address=0x{only.address:02x}  t={only.time_s:.9f} s\n" + blocks[0]
    for address, device in standins.items():
        with device.lock:
            table = format_i2cdump(device.dump())
        if len(chosen) == 1:  # one chip: exactly what i2cdump prints (for i2c-stub-from-dump)
            blocks.append(table)
        else:
            blocks.append(f"{DUMP_TITLE}  address=0x{address:02x}  stand-in={device.name}\n"
                          + table)
    text = "\n".join(blocks)
    if args.output is not None:
        from bmg160_emu.io.atomic import atomic_open

        try:  # whole or not at all: a full disk keeps the old file (io.atomic)
            with atomic_open(args.output, "w", encoding="utf-8") as handle:
                handle.write(text)
        except OSError as exc:
            raise CommandError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    else:
        sys.stdout.write(text)
    return 0
