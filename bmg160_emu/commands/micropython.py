"""``bmg160-emu micropython``: run a MicroPython program (main.py) on a PC against emulated
chips, with ``machine`` and MicroPython's ``time`` from the drop-ins."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bmg160_emu.commands._chip_options import add_chip_options, buses_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_bus_option,
    add_command_parser,
    add_renamed_option,
    duration_seconds,
    integer_at_least,
)

EPILOG = """\
examples:
  bmg160-emu micropython main.py                      # the chip at 0x68 on I2C(1)
  bmg160-emu micropython --seed 7 --true-rate 10 0 -5 --duration 2s main.py
  bmg160-emu micropython --part bmi088_gyro --device bmi088_accel@0x18 main.py
  bmg160-emu micropython --bus 0 --realtime main.py  # on I2C(0), in real time

The program imports machine and time as on the board (an ESP32): machine.I2C(BUS) and
every SoftI2C reach the chips, time.sleep_ms() and time.ticks_ms() are there. Without
--realtime the chips' clock follows the program's sleeps: a sleep_ms(10) moves them 10 ms
on at once, so the program runs faster than real time and the same every run (with
--seed). Its folder and its lib folder are on the import path. --duration stops the
program at its first sleep past that much program time (main.py often loops for ever).
Exit status: the program's (1 after an uncaught exception).
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "micropython",
        "run a MicroPython program (main.py) against emulated chips",
        ("Run main.py as on a MicroPython board, with machine.I2C and MicroPython's time "
         "functions reaching emulated chips on a clock that follows the program's sleeps."),
        EPILOG,
    )
    add_bus_option(parser, "the I2C id the chips are on, machine.I2C(N) (default 1)", default=1)
    parser.add_argument("--realtime", dest="real_time", action="store_true",
                        help="the chips on the wall clock; the program's sleeps really wait")
    add_renamed_option(parser, "--real-time", "--realtime", dest="real_time", nargs=0,
                       const=True)
    parser.add_argument("--duration", type=duration_seconds, default=None, metavar="TIME",
                        help="stop the program at its first sleep past TIME of program time "
                             "(30s, 5min)")
    parser.add_argument("--heap", type=integer_at_least(1024, "--heap"), default=None,
                        metavar="BYTES",
                        help="the board's heap: a buffer past it is a MemoryError (an ESP32 "
                             "without PSRAM has about 110000); default: no limit")
    add_chip_options(parser, realtime=False, devices=True)
    parser.add_argument("program", type=Path, metavar="PROGRAM",
                        help="the MicroPython program, e.g. main.py")
    parser.add_argument("args", nargs=argparse.REMAINDER, metavar="ARGS",
                        help="its sys.argv[1:]")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.clock import RealTimeClock, VirtualClock
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.session.micropython_program import run_program

    if not args.program.is_file():
        raise CommandError(f"{args.program}: no such program")
    clock = RealTimeClock() if args.real_time else VirtualClock()
    placed = buses_from_args(args, args.bus, clock=clock)
    buses = {number: I2CBus(number, devices) for number, devices in sorted(placed.items())
             if number is not None}
    where = ("the chips are on " + ", ".join(f"I2C({n})" for n in buses)
             + "; --bus N puts them on I2C(N)")
    result = run_program(args.program, buses, clock, argv=args.args, real_time=args.real_time,
                         duration_s=args.duration, heap_bytes=args.heap, where=where,
                         warn=lambda text: print(f"bmg160-emu micropython: warning: {text}",
                                                 file=sys.stderr))
    if result.stopped:
        print(f"bmg160-emu micropython: {args.program.name} stopped after "
              f"{result.time_s:g} s of program time (--duration)", file=sys.stderr)
    return result.status
