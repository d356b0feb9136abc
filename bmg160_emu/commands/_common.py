"""Argument types, options, checks and the script-file runner shared by the sub-commands."""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol


class Subparsers(Protocol):
    """What ``ArgumentParser.add_subparsers()`` returns, as the commands use it (argparse
    names its class only privately)."""

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser: ...


class CommandError(Exception):
    """A user-facing error: printed as one line, exit status 2, never a traceback;
    ``details``, lines printed under it (a script's list of mistakes, one per line, as a
    compiler lists them)."""

    def __init__(self, message: str, details: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.details = tuple(details)


def integer_at_least(minimum: int, what: str) -> Callable[[str], int]:
    """An argparse type: an integer (``0x`` and ``0o`` prefixes allowed) of at least
    ``minimum``; anything else is a usage error naming ``what``."""

    def parse(text: str) -> int:
        try:
            value = int(text, 0)
        except ValueError:
            value = minimum - 1
        if value < minimum:
            raise argparse.ArgumentTypeError(
                f"{what} must be an integer >= {minimum}, not {text!r}"
            )
        return value

    parse.__name__ = what.replace(" ", "_")  # argparse names the type in some messages
    return parse


def bus_number(text: str) -> int:
    """An argparse type: a Linux I2C bus number (limits.I2C_BUS)."""
    from bmg160_emu.limits import I2C_BUS

    return bounded_option(I2C_BUS)(text)


bus_number.__name__ = "bus"


def bounded_option(bounded: Any) -> Callable[[str], Any]:
    """An argparse type reading an option's value through a :class:`bmg160_emu.limits.Bounded`:
    a finite number in its stated range, or a usage error (argparse names the option) giving
    the range."""
    from bmg160_emu.limits import LimitError

    def parse(text: str) -> Any:
        try:
            return bounded.parse(text)
        except LimitError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = bounded.name.replace(" ", "_")
    return parse


def parsed_duration(text: str, option: str, *, allow_zero: bool = False) -> float:
    """A duration option read after parsing (``--duration``, ``--skip``, ``--block``): seconds,
    or a :class:`CommandError` naming ``option``."""
    from bmg160_emu.durations import parse_duration

    try:
        return parse_duration(text, allow_zero=allow_zero)
    except ValueError as exc:
        raise CommandError(f"{option}: {exc}") from None


def add_bus_option(parser: argparse.ArgumentParser, help_text: str, **kwargs: Any) -> None:
    """``--bus N``: the I2C bus number of ``/dev/i2c-N``."""
    parser.add_argument("--bus", type=bus_number, metavar="N", help=help_text, **kwargs)


def duration_seconds(text: str) -> float:
    """An argparse type: a positive duration (``30s``, ``5min``, a bare number of seconds)
    read by :func:`bmg160_emu.durations.parse_duration`, in seconds."""
    from bmg160_emu.durations import parse_duration

    try:
        return parse_duration(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


duration_seconds.__name__ = "duration"  # argparse names the type in some messages

# argparse takes a word that starts with '-' for an option unless it looks like a negative
# number, so "--duration -5s" used to fail with "expected one argument". Negative durations
# count as negative numbers here, and reach the duration parser, which says what is wrong.
_NEGATIVE_NUMBER_OR_DURATION = re.compile(r"^-((\d+\.?\d*|\.\d+)(e[+-]?\d+)?[a-z]*|inf|infinity|nan)$",
                                          re.IGNORECASE)


def add_command_parser(
    subparsers: Subparsers, name: str, summary: str, description: str, epilog: str
) -> argparse.ArgumentParser:
    """The sub-command's parser: one-line ``summary`` for the command list, ``description``
    and an ``epilog`` of examples shown as written."""
    parser = subparsers.add_parser(
        name,
        help=summary,
        description=description,
        epilog=epilog,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    accept_negative_durations(parser)
    return parser


def accept_negative_durations(parser: argparse.ArgumentParser) -> None:
    """Let ``-5s`` (and ``-5``) be an option's value on ``parser``, as a negative number is."""
    if hasattr(parser, "_negative_number_matcher"):  # CPython's argparse since 2.7
        parser._negative_number_matcher = _NEGATIVE_NUMBER_OR_DURATION


def add_file_option(parser: argparse.ArgumentParser, flag: str, metavar: str, help_text: str) -> None:
    """An optional ``flag FILE`` giving a path (None when absent)."""
    parser.add_argument(flag, type=Path, default=None, metavar=metavar, help=help_text)


def check_writable(path: Path) -> None:
    """Refuse an output path that cannot be written before any work is done (a long
    recording would otherwise be lost at the end): io.atomic's check, as a CommandError."""
    from bmg160_emu.io.atomic import OutputError
    from bmg160_emu.io.atomic import check_writable as check

    try:
        check(path)
    except OutputError as exc:
        raise CommandError(str(exc)) from None


def run_script_file(
    path: Path, chips: Mapping[int, Any], log: Callable[[str], None], failed_prefix: str
) -> int:
    """Run a register script file on an I2C bus over ``chips`` (the first is the default chip).

    A script that cannot be read or parsed is a :class:`CommandError`; a failed expectation is
    printed to stderr after ``failed_prefix`` and gives exit status 1, else 0.
    """
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.session.script import run_script
    from bmg160_emu.session.script_language import ScriptFailure, ScriptSyntaxError, read_script

    chip = next(iter(chips.values()))
    try:
        text = read_script(path)
        run_script(text, chip, log, str(path), bus=I2CBus(1, chips))
    except OSError as exc:
        raise CommandError(f"cannot read {path}: {exc.strerror}") from None
    except ScriptSyntaxError as exc:  # the first mistake, then the others a line each
        first, *others = exc.lines or [str(exc)]
        raise CommandError(first, others) from None
    except ScriptFailure as exc:
        print(f"{failed_prefix}{exc}", file=sys.stderr)
        return 1
    return 0


def memory_room() -> tuple[int, str]:
    """Bytes this process can still allocate, and what bounds it: its address-space limit
    (``ulimit -v``) less what it already maps, or the system's available memory and free
    swap (/proc/meminfo), whichever is less. Without /proc (not Linux): no bound known."""
    import resource

    room, why = 2**62, "no limit known"
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    status = _proc_fields("/proc/self/status")
    if soft != resource.RLIM_INFINITY and "VmSize" in status:
        room, why = soft - status["VmSize"], "its address-space limit, ulimit -v"
    info = _proc_fields("/proc/meminfo")
    if "MemAvailable" in info:
        free = info["MemAvailable"] + info.get("SwapFree", 0)
        if free < room:
            room, why = free, "the memory and swap this machine has free"
    return max(room, 0), why


def _proc_fields(path: str) -> dict[str, int]:
    """``Name:   123 kB`` lines of a /proc file, in bytes."""
    fields: dict[str, int] = {}
    try:
        with open(path, encoding="ascii") as handle:
            for line in handle:
                name, _, value = line.partition(":")
                parts = value.split()
                if len(parts) == 2 and parts[1] == "kB" and parts[0].isdigit():
                    fields[name] = int(parts[0]) * 1024
    except OSError:
        pass
    return fields


def check_memory(need_bytes: float, what: str, remedy: str) -> None:
    """Refuse, before the work, a job that cannot hold what it must (a CommandError giving
    the figures): one that would fail on its last step, or be killed, hours in (issue 35:
    ``record --duration 50000s`` at 2000 Hz under a 4 GiB limit died after 1.8 s with an
    allocation traceback)."""
    from bmg160_emu.io.atomic import size_text

    room, why = memory_room()
    if need_bytes > room:
        raise CommandError(f"{what} needs about {size_text(int(need_bytes))} of memory; this "
                           f"process can have {size_text(room)} more ({why}): {remedy}")


def add_progress_options(parser: argparse.ArgumentParser) -> None:
    """``--progress`` / ``--no-progress``, one spelling on every command that can run long:
    a line with the time left, by default only when stderr is a terminal (a long job says
    its estimate either way, bmg160_emu.progress)."""
    bar = parser.add_mutually_exclusive_group()
    bar.add_argument("--progress", dest="progress", action="store_true", default=None,
                     help="show the progress line even when stderr is not a terminal "
                     "(default: only on a terminal)")
    bar.add_argument("--no-progress", dest="progress", action="store_false",
                     help="no progress line (a job estimated at over a minute still says so)")


def progress_for(args: argparse.Namespace, command: str, on_stop: str | None = None) -> Any:
    """The :class:`bmg160_emu.progress.Progress` of ``bmg160-emu COMMAND`` as its options
    ask (``args.progress``: None, True or False); ``on_stop``: what a ^C keeps, when it is
    not what is finished."""
    from bmg160_emu.progress import Progress

    progress = Progress(f"bmg160-emu {command}", enabled=getattr(args, "progress", None))
    if on_stop is not None:
        progress.on_stop = on_stop
    return progress


def add_renamed_option(parser: Any, old: str, new: str, **kwargs: Any) -> None:
    """``old``, an earlier spelling of the option ``new``, kept for one release and hidden
    from the help (CHANGELOG.md lists each): it sets the same value as ``new`` and says the
    new spelling on stderr, so scripts keep working while they are updated."""
    parser.add_argument(old, action=_RenamedOption, new=new, help=argparse.SUPPRESS, **kwargs)


class _RenamedOption(argparse.Action):
    def __init__(self, option_strings: list[str], dest: str, new: str, **kwargs: Any) -> None:
        self.new = new
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        print(f"{parser.prog}: note: {option_string} is now spelled {self.new} (the old "
              "spelling goes in the next release; CHANGELOG.md)", file=sys.stderr)
        setattr(namespace, self.dest, self.const if self.nargs == 0 else values)


def profile_named(profile: Any, message: str) -> str:
    """A noise profile's error, named by the profile as the user gave it: the file, or the
    built-in name (``paper mode needs sigma_gyro ...`` named neither, issue 35)."""
    if profile is None or str(profile) in message:
        return message
    shown = str(profile)
    return f"{shown}: {message}" if Path(shown).suffix else f"profile {shown}: {message}"
