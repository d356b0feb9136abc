"""Command-line options that build emulated chips, shared by every sub-command.

``add_chip_options(parser)`` adds the options; ``chips_from_args(args)`` turns them into
``{address: BMG160}``, all chips sharing one clock so they stay in step; both go through
:class:`~bmg160_emu.device.config.ChipConfig` (``configs_from_args``), as trace headers do.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from bmg160_emu.device.config import ChipConfig
from bmg160_emu.device.registers import address_of
from bmg160_emu.device.spec_choices import DEFAULT_ADDRESS, RANGE_CODE_BY_DPS, VALID_ADDRESSES

if TYPE_CHECKING:  # the chip module is imported lazily to keep ``--help`` fast
    from bmg160_emu.device.chip import BMG160

RANGE = address_of("RANGE")  # --range is written here at start (spec 4.8)
BW = address_of("BW")  # --bandwidth is written here at start (spec 5.3)


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


def configs_from_args(args: argparse.Namespace) -> list[ChipConfig]:
    """One :class:`ChipConfig` per ``--address`` (default 0x68) from parsed options.

    The chips of a session and the header of its trace are both made from these, so an
    option given here reaches replay.
    """
    setup: list[tuple[int, bytes]] = []
    if getattr(args, "range_dps", None) is not None:
        setup.append((RANGE, bytes([RANGE_CODE_BY_DPS[args.range_dps]])))
    if getattr(args, "bandwidth", None) is not None:
        setup.append((BW, bytes([args.bandwidth])))
    rate = getattr(args, "true_rate", None)
    return [
        ChipConfig(
            address=address,
            profile=getattr(args, "profile", "paper"),
            noise=not getattr(args, "no_noise", False),
            noise_mode=getattr(args, "noise_mode", "physical"),
            sensitivity=getattr(args, "sensitivity", "binary"),
            temperature_c=getattr(args, "temperature", 23.0),
            strict=getattr(args, "strict", False),
            true_rate_dps=None if rate is None else tuple(rate),
            setup_writes=list(setup),
        )
        for address in dict.fromkeys(getattr(args, "addresses", None) or [DEFAULT_ADDRESS])
    ]


def chips_from_args(args: argparse.Namespace) -> dict[int, BMG160]:
    """Build ``{address: BMG160}`` from parsed options; every chip shares one clock."""
    from bmg160_emu.clock import RealTimeClock, VirtualClock

    clock = RealTimeClock() if getattr(args, "realtime", False) else VirtualClock()
    chips: dict[int, BMG160] = {}
    for config in configs_from_args(args):
        try:
            chip = config.build(getattr(args, "seed", None), clock)
        except (ValueError, KeyError, OSError) as exc:
            from bmg160_emu.commands._common import CommandError

            raise CommandError(str(exc)) from None
        chips[config.address] = chip
    return chips
