"""``bmg160-emu run``: run an unmodified program against emulated chips on a virtual /dev/i2c-N."""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import sys
from pathlib import Path

from bmg160_emu.commands._chip_options import add_chip_options, chips_from_args

EPILOG = """\
examples:
  bmg160-emu run -- i2cget -y 1 0x68 0x00          # prints 0x0f
  bmg160-emu run --bus 3 --seed 7 -- python3 my_driver.py
  bmg160-emu run --address 0x68 --address 0x69 -- i2cdetect -y -r 1

The program runs under umockdev's preload library: its open/ioctl/read/write on
/dev/i2c-BUS are answered by the emulator, in real time. Statically linked programs,
raw syscalls and setuid programs are not intercepted. Exit status: the program's.
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "run",
        help="run a program against emulated chips on a virtual /dev/i2c-N (umockdev)",
        description=(
            "Run an unmodified program (i2c-tools, smbus2 scripts, C code using ioctl) with a "
            "virtual /dev/i2c-BUS whose transactions the emulated BMG160 answers."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--bus", type=_bus_number, default=1, help="I2C bus number N of /dev/i2c-N (default 1)"
    )
    parser.add_argument(
        "--log", type=Path, default=None, metavar="FILE",
        help="write the transaction log to FILE when the program ends",
    )
    add_chip_options(parser)
    parser.add_argument("program", nargs=argparse.REMAINDER, help="-- COMMAND ARGS...")
    parser.set_defaults(func=run)


def _bus_number(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"bus must be an integer >= 0, not {text!r}")
    return value


def _is_static(path: str) -> bool:
    """An ELF without a program interpreter: LD_PRELOAD cannot reach it."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(65536)
    except OSError:
        return False
    return head.startswith(b"\x7fELF") and b"ld-linux" not in head and b"ld-musl" not in head


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.cli import CommandError
    from bmg160_emu.i2c_bus import I2CBus
    from bmg160_emu.linux.umockdev_node import UMockdevUnavailable, VirtualI2CDevices

    program = list(args.program)
    if program and program[0] == "--":
        program = program[1:]
    if not program:
        raise CommandError("no program given: bmg160-emu run [options] -- COMMAND ARGS...")
    executable = shutil.which(program[0])
    if executable is None:
        raise CommandError(f"command not found: {program[0]}")
    if _is_static(executable):
        print(
            f"bmg160-emu run: warning: {program[0]} is statically linked; its accesses to "
            f"/dev/i2c-{args.bus} will not reach the emulator",
            file=sys.stderr,
        )
    args.realtime = True  # an unmodified program lives in real time
    chips = chips_from_args(args)
    bus = I2CBus(args.bus, chips)
    try:
        devices = VirtualI2CDevices([bus])
    except UMockdevUnavailable as exc:
        raise CommandError(str(exc)) from None
    with devices:
        process = devices.popen(program)
        # ^C reaches the child from the terminal; SIGTERM and SIGHUP sent to us are passed on,
        # so the program never outlives the emulator that answers it.
        previous = {
            signal.SIGINT: signal.signal(signal.SIGINT, signal.SIG_IGN),
            signal.SIGTERM: signal.signal(signal.SIGTERM, lambda n, _: process.send_signal(n)),
            signal.SIGHUP: signal.signal(signal.SIGHUP, lambda n, _: process.send_signal(n)),
        }
        try:
            status = process.wait()
        finally:
            for number, handler in previous.items():
                signal.signal(number, handler)
        for error in devices.handler_errors():
            print(f"bmg160-emu run: internal error answered as EIO: {error}", file=sys.stderr)
    if args.log is not None:
        args.log.write_text(str(bus.log) + os.linesep)
    return 128 - status if status < 0 else status
