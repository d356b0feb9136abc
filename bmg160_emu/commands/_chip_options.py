"""Command-line options that build emulated chips, shared by every sub-command.

``add_chip_options(parser)`` adds the options; ``chips_from_args(args)`` turns them into
``{address: BMG160}``, all chips sharing one clock so they stay in step.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the chip module is imported lazily to keep ``--help`` fast
    from bmg160_emu.device.chip import BMG160

# Full scale in deg/s -> RANGE code (spec 4.8).
RANGE_CODE_BY_DPS = {2000: 0, 1000: 1, 500: 2, 250: 3, 125: 4}
VALID_ADDRESSES = (0x68, 0x69)  # spec 2.1


def _address(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an I2C address: {text!r}") from None
    if value not in VALID_ADDRESSES:
        raise argparse.ArgumentTypeError(
            f"the BMG160 answers at 0x68 or 0x69 only, not {text}"
        )
    return value


def _range_dps(text: str) -> int:
    try:
        value = int(float(text))
    except ValueError:
        value = -1
    if value not in RANGE_CODE_BY_DPS:
        raise argparse.ArgumentTypeError(
            f"range must be one of {sorted(RANGE_CODE_BY_DPS)} deg/s, not {text}"
        )
    return value


def _bandwidth_code(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        value = -1
    if not 0 <= value <= 7:
        raise argparse.ArgumentTypeError(f"bandwidth code must be 0..7 (spec 5.3), not {text}")
    return value


def add_chip_options(parser: argparse.ArgumentParser, *, realtime: bool = True) -> None:
    """Add the options that describe the emulated chip(s) to ``parser``; ``realtime=False``
    where the command fixes the clock itself (an option that did nothing is not offered)."""
    group = parser.add_argument_group("emulated chip")
    group.add_argument("--seed", type=int, default=None, help="master noise seed (default: random)")
    group.add_argument("--profile", default="paper", help="noise profile name (default: paper)")
    group.add_argument("--no-noise", action="store_true", help="noiseless chip")
    group.add_argument(
        "--noise-mode",
        choices=("physical", "paper"),
        default="physical",
        help="noise discretisation (default: physical)",
    )
    group.add_argument(
        "--true-rate",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        default=None,
        help="constant true angular rate in deg/s",
    )
    group.add_argument(
        "--range",
        dest="range_dps",
        type=_range_dps,
        default=None,
        metavar="DPS",
        help="full-scale range written to RANGE at start: 2000, 1000, 500, 250 or 125",
    )
    group.add_argument(
        "--bandwidth",
        type=_bandwidth_code,
        default=None,
        metavar="CODE",
        help="BW code 0..7 written to BW at start (spec 5.3)",
    )
    group.add_argument(
        "--address",
        dest="addresses",
        type=_address,
        action="append",
        default=None,
        help="I2C address of a chip, 0x68 or 0x69; repeat for two chips (default 0x68)",
    )
    group.add_argument(
        "--sensitivity",
        choices=("binary", "nominal"),
        default="binary",
        help="sensitivity table: binary 32768/FS (default) or nominal 16.4*2^code",
    )
    group.add_argument(
        "--temperature",
        type=float,
        default=23.0,
        metavar="DEGC",
        help="die temperature in deg C (default 23)",
    )
    if realtime:  # not where the command fixes the clock itself (run, stub, record)
        group.add_argument(
            "--realtime",
            action="store_true",
            help="run on a real-time clock instead of virtual time",
        )
    group.add_argument(
        "--strict", action="store_true", help="log questionable driver behaviour"
    )


def chips_from_args(args: argparse.Namespace) -> dict[int, BMG160]:
    """Build ``{address: BMG160}`` from parsed options; every chip shares one clock."""
    from bmg160_emu.clock import RealTimeClock, VirtualClock
    from bmg160_emu.device.chip import BMG160

    clock = RealTimeClock() if getattr(args, "realtime", False) else VirtualClock()
    addresses = list(dict.fromkeys(getattr(args, "addresses", None) or [0x68]))
    chips: dict[int, BMG160] = {}
    for address in addresses:
        try:
            chip = BMG160(
                seed=getattr(args, "seed", None),
                profile=getattr(args, "profile", "paper"),
                noise=not getattr(args, "no_noise", False),
                noise_mode=getattr(args, "noise_mode", "physical"),
                clock=clock,
                address=address,
                sensitivity=getattr(args, "sensitivity", "binary"),
                temperature_c=getattr(args, "temperature", 23.0),
                strict=getattr(args, "strict", False),
            )
        except (ValueError, KeyError, OSError) as exc:
            from bmg160_emu.cli import CommandError

            raise CommandError(str(exc)) from None
        if getattr(args, "true_rate", None) is not None:
            try:
                chip.set_true_rate(tuple(args.true_rate))
            except ValueError as exc:
                from bmg160_emu.cli import CommandError

                raise CommandError(f"--true-rate: {exc}") from None
        if getattr(args, "range_dps", None) is not None:
            chip.write(0x0F, bytes([RANGE_CODE_BY_DPS[args.range_dps]]))
        if getattr(args, "bandwidth", None) is not None:
            chip.write(0x10, bytes([args.bandwidth]))
        chips[address] = chip
    return chips
