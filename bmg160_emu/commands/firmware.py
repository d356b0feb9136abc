"""``bmg160-emu firmware``: build the ATmega328P firmware, or capture its UART stream in simavr."""

from __future__ import annotations

import argparse
from pathlib import Path

from bmg160_emu import limits
from bmg160_emu.commands._common import (
    Subparsers,
    add_command_parser,
    add_progress_options,
    add_renamed_option,
    bounded_option,
    duration_seconds,
    progress_for,
)

STREAM_LINE_BYTES = 12  # the shortest line of the UART stream ("1 0 0 0\n" is 8; most ~20)

EPILOG = """\
examples:
  bmg160-emu firmware build --profile paper
  bmg160-emu firmware build --profile paper --address 0x69 --out build/gyro69
  bmg160-emu firmware capture --duration 60s --rate 200 -o stream.txt

'build' writes bmg160_params.h (noise coefficients, register table, I2C address) and builds
bmg160.elf and bmg160.hex with Debian's gcc-avr. Flash the HEX onto an Arduino Uno/Nano:
  avrdude -p m328p -c arduino -P /dev/ttyUSB0 -b 115200 -U flash:w:bmg160.hex:i
(-b 57600 for a Nano with the old bootloader). 'capture' runs the firmware in simavr and
writes its UART sample stream (docs/firmware.md), which `bmg160-emu identify` reads.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "firmware",
        "build the ATmega328P firmware or capture its output in simavr",
        "The BMG160 firmware for an ATmega328P board: I2C slave at 0x68/0x69 "
        "with on-chip noise and a UART sample stream.",
        EPILOG,
    )
    actions = parser.add_subparsers(dest="firmware_action", metavar="ACTION")
    build = actions.add_parser(
        "build",
        help="write the parameter header and build ELF/HEX",
        description="Write bmg160_params.h for a noise profile and build bmg160.elf/.hex.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _common(build)
    build.set_defaults(func=run_build)
    capture = actions.add_parser(
        "capture",
        help="run the firmware in simavr and write its UART stream",
        description="Build (if needed) and run the firmware in simavr for a simulated time, "
        "writing its UART sample stream to a file.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _common(capture)
    capture.add_argument("--duration", type=duration_seconds, required=True, metavar="TIME",
                         help="simulated time: 10s, 5min, 2h, 1d, or seconds (at most 30 days)")
    add_renamed_option(capture, "--seconds", "--duration", dest="duration",
                       type=duration_seconds)
    capture.add_argument("--rate", type=bounded_option(limits.ODR_HZ), default=200,
                         choices=(100, 200, 400, 1000, 2000), metavar="HZ",
                         help="output data rate: 100, 200, 400, 1000 or 2000 Hz (default 200)")
    add_renamed_option(capture, "--odr", "--rate", dest="rate",
                       type=bounded_option(limits.ODR_HZ), choices=(100, 200, 400, 1000, 2000))
    capture.add_argument("-o", "--output", required=True, metavar="FILE",
                         help="file for the UART stream")
    add_progress_options(capture)
    capture.set_defaults(func=run_capture)
    parser.set_defaults(func=lambda args: _missing_action(parser))


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--profile", default="paper", metavar="NAME|FILE",
                        help="noise profile name or TOML file")
    parser.add_argument(
        "--address", default="0x68", help="7-bit I2C address: 0x68 (SDO low) or 0x69 (SDO high)"
    )
    parser.add_argument(
        "--noise-mode", default="physical", choices=("physical", "paper"),
        help="noise discretisation (default: physical)"
    )
    add_renamed_option(parser, "--mode", "--noise-mode", dest="noise_mode",
                       choices=("physical", "paper"))
    parser.add_argument("--seed", type=bounded_option(limits.FIRMWARE_SEED), default=1,
                        metavar="N", help="seed of the on-chip generator")
    parser.add_argument(
        "--normal",
        default="ziggurat",
        choices=("ziggurat", "polar", "box-muller"),
        help="normal generator: ziggurat (default, fastest), Marsaglia's polar form or the "
        "paper's trigonometric Box-Muller",
    )
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="build folder (default firmware/build/...)")


def _missing_action(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 2


def _build(args: argparse.Namespace):
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.firmware.build import FirmwareToolError, build_firmware

    try:
        address = int(args.address, 0)
    except ValueError:
        raise CommandError(f"--address {args.address!r} is not a number (use 0x68 or 0x69)")
    try:
        return build_firmware(
            profile=args.profile,
            address=address,
            mode=args.noise_mode,
            seed=args.seed,
            normal=args.normal,
            out_dir=args.out,
        )
    except (ValueError, FirmwareToolError) as exc:
        raise CommandError(str(exc).replace("\n", " | ")) from None
    except OSError as exc:  # the build folder cannot be made or written
        where = exc.filename or args.out
        raise CommandError(f"cannot build in {where}: {exc.strerror}") from None


def run_build(args: argparse.Namespace) -> int:
    from bmg160_emu.firmware.build import ATMEGA328P_FLASH, ATMEGA328P_SRAM
    from bmg160_emu.firmware.params_header import unapplied_output_note

    build = _build(args)
    note = unapplied_output_note(args.profile)
    if note:
        print(note)
    print(f"header: {build.header}")
    print(f"elf:    {build.elf}")
    print(f"hex:    {build.hex}")
    print(
        f"flash:  {build.flash_bytes} of {ATMEGA328P_FLASH} bytes; static RAM: "
        f"{build.ram_bytes} of {ATMEGA328P_SRAM} bytes (the stack uses the rest)"
    )
    return 0


def run_capture(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError, check_writable
    from bmg160_emu.firmware.build import FirmwareToolError, capture_uart
    from bmg160_emu.io.atomic import OutputError, atomic_path, check_free_space

    output = Path(args.output)
    check_writable(output)
    lines = round(args.duration * args.rate)
    try:  # a low estimate, so a disk that would hold it is never refused
        check_free_space(output, lines * STREAM_LINE_BYTES)
    except OutputError as exc:
        raise CommandError(str(exc)) from None
    build = _build(args)
    try:  # the stream appears under its name only when complete (docs/commands/firmware.md)
        with atomic_path(output) as partial, \
                progress_for(args, "firmware capture", on_stop="^C stops it and keeps "
                             "nothing (the stream is one piece)").stage(lines, "samples") \
                as update:
            capture_uart(build, args.duration, partial, odr_hz=args.rate,
                         progress=lambda done, total: update(done))
    except (ValueError, FirmwareToolError) as exc:
        raise CommandError(str(exc).replace("\n", " | ")) from None
    except OSError as exc:
        raise CommandError(f"cannot write {output}: {exc.strerror or exc}") from None
    print(f"wrote {output} ({args.duration:g} simulated s at {args.rate} Hz)")
    return 0
