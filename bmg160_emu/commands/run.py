"""``bmg160-emu run``: run an unmodified program against emulated chips on a virtual /dev/i2c-N."""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import signal
import subprocess
import sys
from typing import Any

from bmg160_emu.commands._chip_options import add_chip_options, buses_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_bus_option,
    add_command_parser,
    add_file_option,
)

EPILOG = """\
examples:
  bmg160-emu run -- i2cget -y 1 0x68 0x00          # prints 0x0f
  bmg160-emu run --bus 3 --seed 7 -- python3 my_driver.py
  bmg160-emu run --address 0x68 --address 0x69 -- i2cdetect -y -r 1
  bmg160-emu run --part bmi088_gyro --address 0x69 --device bmi088_accel@0x19 -- ./probe
  bmg160-emu run --device bmg160@0x68 --device bmm150@0x10:2 -- i2cdetect -y 2
  bmg160-emu run --seed 7 --trace session.jsonl -- i2cdump -y 1 0x68 i
  bmg160-emu trace session.jsonl                    # the session, register by register

The program runs under umockdev's preload library: its open/ioctl/read/write on
/dev/i2c-BUS are answered by the emulator, in real time. Statically linked programs,
raw syscalls and setuid programs are not intercepted. Exit status: the program's.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "run",
        "run a program against emulated chips on a virtual /dev/i2c-N (umockdev)",
        (
            "Run an unmodified program (i2c-tools, smbus2 scripts, C code using ioctl) with a "
            "virtual /dev/i2c-BUS whose transactions the emulated BMG160 answers."
        ),
        EPILOG,
    )
    add_bus_option(parser, "I2C bus number N of /dev/i2c-N (default 1)", default=1)
    add_file_option(
        parser, "--log", "FILE", "write the transaction log to FILE when the program ends"
    )
    add_file_option(
        parser, "--trace", "OUT.jsonl",
        "record every transaction as a JSON Lines trace (decode: bmg160-emu trace FILE)",
    )
    add_chip_options(parser, realtime=False, devices=True)
    parser.add_argument("program", nargs=argparse.REMAINDER, metavar="PROGRAM",
                        help="-- COMMAND ARGS...")
    parser.add_argument(
        "--watch", action="store_true", help="make the session watchable live (bmg160-emu watch)"
    )
    parser.set_defaults(func=run)


def _is_static(path: str) -> bool:
    """An ELF without a program interpreter: LD_PRELOAD cannot reach it."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(65536)
    except OSError:
        return False
    return head.startswith(b"\x7fELF") and b"ld-linux" not in head and b"ld-musl" not in head


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.commands._chip_options import close_trace
    from bmg160_emu.commands._common import CommandError, check_writable
    from bmg160_emu.device.contract import RateSensor
    from bmg160_emu.io.atomic import atomic_open
    from bmg160_emu.linux.umockdev import (
        RequestClock,
        UMockdevUnavailable,
        VirtualI2CDevices,
    )

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
    # An unmodified program lives in real time. The chips are built and set up at t = 0 of
    # a virtual clock, as a trace replay builds them, then run on real time from 0 on: built
    # on a running clock they would start sampling wherever their construction ended
    # (~15 ms each), and a replay of the session would sample at other instants.
    args.realtime = False
    placed: dict[Any, Any] = buses_from_args(args, args.bus)  # {bus: {address: device}}; --device ...:BUS
    clock = RequestClock()
    chips: dict[int, Any] = {}  # the gyros, for --watch
    for on_bus in placed.values():
        for address, chip in on_bus.items():
            with chip.lock:
                chip.clock = clock
            if isinstance(chip, RateSensor):  # a stand-in has no rate to watch
                chips.setdefault(address, chip)
    buses = [I2CBus(number, on_bus) for number, on_bus in sorted(placed.items())]
    try:
        devices = VirtualI2CDevices(buses)
    except UMockdevUnavailable as exc:
        raise CommandError(f"{exc}; `bmg160-emu doctor umockdev` prints the install lines for "
                           "this system") from None
    if args.log is not None:  # checked now: a bad path is an error before the program runs
        check_writable(args.log)
    writer = _trace_writer(args, buses)
    try:
        with devices, contextlib.ExitStack() as watching:
            if args.watch:  # a live view (commands/watch.py); the program runs unchanged
                from bmg160_emu.watch.session import WatchError, watched

                try:
                    watching.enter_context(
                        watched(chips, [b.log for b in buses], f"run {program[0]}"))
                except (WatchError, OSError) as exc:
                    raise CommandError(f"--watch: {exc}") from None
            status = _run_program(devices, program)
            for error in devices.handler_errors():
                print(f"bmg160-emu run: internal error answered as EIO: {error}", file=sys.stderr)
    finally:
        try:
            if writer is not None:
                close_trace(writer, args.trace)  # the transactions so far, also when stopped
        finally:
            if args.log is not None:  # whole or not at all; an existing log kept until then
                try:
                    with atomic_open(args.log, "w", encoding="utf-8") as log_file:
                        for bus in buses:
                            log_file.write(str(bus.log) + os.linesep)
                except OSError as exc:
                    raise CommandError(f"cannot write {args.log}: {exc.strerror or exc}") from None
    return 128 - status if status < 0 else status


def _trace_writer(args: argparse.Namespace, buses: list[Any]) -> Any:
    """A TraceWriter fed by every bus's log (None without --trace)."""
    if args.trace is None:
        return None
    from bmg160_emu.commands._chip_options import trace_writer_from_args

    writer = trace_writer_from_args(args)
    for bus in buses:
        bus.log.sinks.append(writer)
    return writer


def _run_program(devices: Any, program: list[str]) -> int:
    """Start the program under the testbed and wait for it; its wait status."""
    process: subprocess.Popen | None = None
    pending: list[int] = []

    def pass_on(number: int, _frame: object) -> None:
        if process is None:
            pending.append(number)  # arrived before the program started
        else:
            process.send_signal(number)

    # ^C reaches the child from the terminal; SIGTERM and SIGHUP sent to us are passed on,
    # so the program never outlives the emulator that answers it. The handlers are in place
    # before the program starts: it may signal us (through a test harness) at once.
    previous = {
        signal.SIGINT: signal.signal(signal.SIGINT, signal.SIG_IGN),
        signal.SIGTERM: signal.signal(signal.SIGTERM, pass_on),
        signal.SIGHUP: signal.signal(signal.SIGHUP, pass_on),
    }
    try:
        process = devices.popen(program)
        for number in pending:
            process.send_signal(number)
        return process.wait()
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
