"""Command-line options that build emulated chips, shared by every sub-command.

``add_chip_options(parser)`` adds the options; ``chips_from_args(args)`` turns them into
``{address: device}`` on the command's bus and ``buses_from_args(args, bus)`` into
``{bus: {address: device}}``, every device sharing one clock so they stay in step; both go
through :class:`~bmg160_emu.device.config.ChipConfig` and
:class:`~bmg160_emu.device.standin.StandinConfig` (``configs_from_args``), as trace headers
do. Without ``--seed`` a session's seed is chosen here, printed to stderr and carried by
the chips (so records and traces name it), as ``generate`` does.

Devices: ``--address`` places chips of ``--part`` (default bmg160); ``--device
NAME@ADDRESS[:BUS]`` places one part or stand-in (docs/sessions.md).
"""

from __future__ import annotations

import argparse
import secrets
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bmg160_emu import limits
from bmg160_emu.commands._common import bounded_option
from bmg160_emu.device.config import ChipConfig
from bmg160_emu.device.registers import address_of
from bmg160_emu.device.spec_choices import (
    DEFAULT_ADDRESS,
    DEFAULT_PART,
    RANGE_CODE_BY_DPS,
    VALID_ADDRESSES,
)

if TYPE_CHECKING:
    from bmg160_emu.io.trace import TraceHeader, TraceWriter

RANGE = address_of("RANGE")  # --range is written here at start (spec 4.8)
BW = address_of("BW")  # --bandwidth is written here at start (spec 5.3)


I2C_ADDRESSES = range(0x03, 0x78)  # the 7-bit addresses i2cdetect scans (0x03..0x77)


@dataclass(frozen=True)
class DeviceOption:
    """One ``--device NAME@ADDRESS[:BUS]``: a part name, or a stand-in (built-in or file)."""

    text: str
    address: int
    bus: int | None
    part: str | None = None
    standin: Any = None  # a StandinSpec


class _PartNames(Sequence):
    """``device.parts.PART_NAMES``, read when argparse first looks (a ``--part`` given, an
    error, ``--help``): building the parsers of every command stays free of the chip model."""

    @staticmethod
    def _names() -> tuple[str, ...]:
        from bmg160_emu.device.parts import PART_NAMES

        return PART_NAMES

    def __getitem__(self, index: Any) -> Any:
        return self._names()[index]

    def __len__(self) -> int:
        return len(self._names())

    def __contains__(self, name: object) -> bool:
        return name in self._names()


def device_option(text: str) -> DeviceOption:
    """Parse ``NAME@ADDRESS[:BUS]``; a bad one is a usage error that quotes it."""
    from bmg160_emu.device.parts import PART_NAMES

    name, at, place = text.rpartition("@")
    if not at or not name or not place:
        raise argparse.ArgumentTypeError(f"{text}: give NAME@ADDRESS[:BUS], e.g. bmg160@0x68")
    address_text, colon, bus_text = place.partition(":")
    try:
        address = int(address_text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text}: not an I2C address: {address_text!r}") from None
    if address not in I2C_ADDRESSES:
        raise argparse.ArgumentTypeError(f"{text}: I2C address must be 0x03..0x77, "
                                         f"not 0x{address:02x}")
    bus = None
    if colon:
        try:
            bus = int(bus_text, 0)
        except ValueError:
            bus = -1
        if bus < 0:
            raise argparse.ArgumentTypeError(f"{text}: bus must be an integer >= 0, "
                                             f"not {bus_text!r}")
    if name in PART_NAMES:
        if address not in VALID_ADDRESSES:
            raise argparse.ArgumentTypeError(
                f"{text}: a {name} answers at 0x68 or 0x69 only, not 0x{address:02x}")
        return DeviceOption(text, address, bus, part=name)
    from bmg160_emu.io.errors import FormatError
    from bmg160_emu.io.standin_file import builtin_names, load_standin

    looks_like_file = "/" in name or "." in name or Path(name).exists()
    if name not in builtin_names() and not looks_like_file:
        raise argparse.ArgumentTypeError(
            f"{text}: unknown device {name!r}: a part ({', '.join(PART_NAMES)}), a stand-in "
            f"({', '.join(builtin_names())}) or a stand-in TOML or dump file")
    try:
        spec = load_standin(name)
    except FormatError as exc:
        raise argparse.ArgumentTypeError(f"{text}: {exc}") from None
    if spec.addresses and address not in spec.addresses:
        allowed = ", ".join(f"0x{a:02x}" for a in spec.addresses)
        raise argparse.ArgumentTypeError(f"{text}: a {spec.name} answers at {allowed} only "
                                         f"(its address pins), not 0x{address:02x}")
    return DeviceOption(text, address, bus, standin=spec)


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
        value = limits.FULL_SCALE_DPS.parse(text)
    except limits.LimitError:
        value = -1
    if value not in RANGE_CODE_BY_DPS:
        raise argparse.ArgumentTypeError(
            f"range must be one of {sorted(RANGE_CODE_BY_DPS)} deg/s, not {text}"
        )
    return value


def _bandwidth_code(text: str) -> int:
    try:
        value = limits.BANDWIDTH_CODE.parse(text)
    except limits.LimitError:
        value = -1
    if not 0 <= value <= 7:
        raise argparse.ArgumentTypeError(f"bandwidth code must be 0..7 (spec 5.3), not {text}")
    return value


def add_chip_options(parser: argparse.ArgumentParser, *, realtime: bool = True,
                     devices: bool = False) -> None:
    """Add the options that describe the emulated chip(s) to ``parser``; ``realtime=False``
    where the command fixes the clock itself (an option that did nothing is not offered),
    ``devices=True`` where the command's session takes other devices (``--device``: run,
    stub, dump, script; not where the session is one gyro's, as record's and demo's are)."""
    group = parser.add_argument_group("emulated chip")
    group.add_argument("--seed", type=bounded_option(limits.SEED), default=None, metavar="N",
                       help="master noise seed (default: random)")
    group.add_argument(
        "--profile", default=None, metavar="NAME|FILE",
        help="noise profile name or TOML (default: the part's own: paper for the bmg160, the "
             "data-sheet profile of the others)",
    )
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
        type=bounded_option(limits.RATE_DPS),
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
        metavar="ADDRESS",
        help="I2C address of a chip, 0x68 or 0x69; repeat for two chips (default 0x68 "
             "unless --device is given)",
    )
    group.add_argument(
        "--part", choices=_PartNames(), default=None, metavar="PART",
        help=f"the part of the chips at --address: %(choices)s (default {DEFAULT_PART}; "
             "given with --device and no --address, one such chip at 0x68)",
    )
    if devices:
        group.add_argument(
            "--device", dest="devices", type=device_option, action="append", default=None,
            metavar="NAME@ADDRESS[:BUS]",
            help="one more device: a part or a stand-in (bmi088_accel, bma2x2_accel, bmm150, "
                 "or a stand-in TOML or dump file) at ADDRESS, on BUS (default: the "
                 "command's bus); repeatable (docs/sessions.md)",
        )
    group.add_argument(
        "--sensitivity",
        choices=("binary", "nominal"),
        default="binary",
        help="sensitivity table: binary 32768/FS (default) or nominal 16.4*2^code",
    )
    group.add_argument(
        "--temperature",
        type=bounded_option(limits.TEMPERATURE_C),
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


def configs_from_args(args: argparse.Namespace) -> list[Any]:
    """One :class:`ChipConfig` per ``--address`` (default 0x68 unless ``--device`` is given)
    and one ChipConfig or StandinConfig per ``--device``, in that order.

    The chips of a session and the header of its trace are both made from these, so an
    option given here reaches replay. Two devices at one address of one bus are refused.
    """
    from bmg160_emu.device.standin import StandinConfig

    setup: list[tuple[int, bytes]] = []
    if getattr(args, "range_dps", None) is not None:
        setup.append((RANGE, bytes([RANGE_CODE_BY_DPS[args.range_dps]])))
    if getattr(args, "bandwidth", None) is not None:
        setup.append((BW, bytes([args.bandwidth])))
    rate = getattr(args, "true_rate", None)
    devices: list[DeviceOption] = list(getattr(args, "devices", None) or [])
    part = getattr(args, "part", None)
    addresses = getattr(args, "addresses", None) or (
        [DEFAULT_ADDRESS] if not devices or part is not None else [])

    def gyro(address: int, part: str, bus: int | None) -> ChipConfig:
        return ChipConfig(
            address=address,
            profile=getattr(args, "profile", None),  # None: the part's own (ChipConfig)
            noise=not getattr(args, "no_noise", False),
            noise_mode=getattr(args, "noise_mode", "physical"),
            sensitivity=getattr(args, "sensitivity", "binary"),
            temperature_c=getattr(args, "temperature", 23.0),
            strict=getattr(args, "strict", False),
            true_rate_dps=None if rate is None else tuple(rate),
            setup_writes=list(setup),
            part=part,
            bus=bus,
        )

    configs: list[Any] = [gyro(a, part or DEFAULT_PART, None) for a in dict.fromkeys(addresses)]
    places: dict[tuple[int | None, int], str] = {
        (None, c.address): f"--address 0x{c.address:02x}" for c in configs}
    for device in devices:
        where = (device.bus, device.address)
        if where in places:
            from bmg160_emu.commands._common import CommandError

            raise CommandError(f"--device {device.text}: {places[where]} is already at that "
                               "address on that bus")
        places[where] = f"--device {device.text}"
        if device.part is not None:
            configs.append(gyro(device.address, device.part, device.bus))
        else:
            configs.append(StandinConfig(device.standin, device.address, device.bus))
    return configs


def session_seed(args: argparse.Namespace, announce: bool = True) -> int | None:
    """The session's master seed: ``--seed``, or one chosen now, kept in ``args`` (so the
    trace header and the record name it) and printed to stderr as ``generate`` does
    (``announce=False``: later, by :func:`announce_seed`, once the session is set up;
    not at all with ``--no-noise``, where no draw depends on it)."""
    if not hasattr(args, "seed"):
        return None
    if args.seed is None:
        args.seed = secrets.randbits(32)
        # a noiseless session draws nothing from its seed: there is nothing to repeat
        args.seed_chosen = not getattr(args, "no_noise", False)
        if announce:
            announce_seed(args)
    elif args.seed < 0:
        from bmg160_emu.commands._common import CommandError

        raise CommandError(f"--seed must be a non-negative integer, not {args.seed}")
    return int(args.seed)


def announce_seed(args: argparse.Namespace) -> None:
    """Print a seed chosen by :func:`session_seed` (once; nothing for a given ``--seed``)."""
    if getattr(args, "seed_chosen", False):
        args.seed_chosen = False
        command = getattr(args, "command", None) or "session"
        print(f"bmg160-emu {command}: seed {args.seed} (random; --seed {args.seed} repeats it)",
              file=sys.stderr)


def buses_from_args(args: argparse.Namespace, bus: int | None, announce: bool = True,
                    clock: Any = None) -> dict[int | None, dict[int, Any]]:
    """Build ``{bus: {address: device}}`` from parsed options (devices without a bus go on
    ``bus``); every device shares one clock (``clock`` when given). A chosen seed is printed
    now, or with ``announce=False`` left to :func:`announce_seed`."""
    from bmg160_emu.clock import RealTimeClock, VirtualClock
    from bmg160_emu.commands._common import CommandError, profile_named
    from bmg160_emu.noise.profile import ProfileError

    configs = configs_from_args(args)
    seed = session_seed(args, announce)
    if clock is None:
        clock = RealTimeClock() if getattr(args, "realtime", False) else VirtualClock()
    buses: dict[int | None, dict[int, Any]] = {}
    for config in configs:
        try:
            device = config.build(seed, clock)
        except ProfileError as exc:  # named by the profile as given (issue 35)
            raise CommandError(profile_named(getattr(config, "profile", None), str(exc))) \
                from None
        except (ValueError, KeyError, OSError) as exc:
            raise CommandError(str(exc)) from None
        number = bus if config.bus is None else config.bus
        chips = buses.setdefault(number, {})
        if config.address in chips:
            raise CommandError(f"two devices at 0x{config.address:02x} on bus {number}")
        chips[config.address] = device
    return buses


def chips_from_args(args: argparse.Namespace, default_bus: int | None = None,
                    announce: bool = True, clock: Any = None) -> dict[int, Any]:
    """Build ``{address: device}`` from parsed options, for commands with one bus (``--bus``,
    else ``default_bus``); every device shares one clock (``clock`` when given). A device
    placed on another bus is refused (before a seed is chosen or anything is built)."""
    bus = getattr(args, "bus", None)
    if bus is None:
        bus = default_bus
    others = sorted({str(c.bus) for c in configs_from_args(args) if c.bus not in (None, bus)})
    if others:
        from bmg160_emu.commands._common import CommandError

        raise CommandError(f"this command drives one bus: a --device on bus "
                           f"{', '.join(others)} has nowhere to go (drop its :BUS)")
    from bmg160_emu.device.contract import RateSensor

    chips = buses_from_args(args, bus, announce, clock).get(bus, {})
    # gyros first: the first device is a command's default chip (a script's, dump --after's)
    return dict(sorted(chips.items(), key=lambda item: not isinstance(item[1], RateSensor)))


def header_from_chip_args(args: Any) -> TraceHeader:
    """The trace header for chips built by ``chips_from_args`` from the same options."""
    from bmg160_emu.session.session_trace import session_header

    return session_header(getattr(args, "seed", None), configs_from_args(args))


def trace_writer_from_args(args: Any) -> TraceWriter:
    """``--trace FILE`` opened with the session's header; an unwritable path is the
    command's one-line error (run, script and vhost-user-i2c share it)."""
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.session.session_trace import open_session_trace

    try:
        return open_session_trace(args.trace, getattr(args, "seed", None), configs_from_args(args))
    except OSError as exc:
        raise CommandError(f"cannot write {args.trace}: {exc.strerror}") from None


def close_trace(writer: TraceWriter, path: Any) -> None:
    """Close a session's trace (``session_trace.close_session_trace``); a write error is the
    command's one-line error."""
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.session.session_trace import close_session_trace

    try:
        close_session_trace(writer, path)
    except OSError as exc:
        raise CommandError(f"cannot write {path}: {exc.strerror or exc}") from None
