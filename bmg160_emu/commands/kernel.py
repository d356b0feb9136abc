"""``bmg160-emu kernel``: run a command in a disposable Linux guest whose kernel talks to the
emulated chips (virtio-i2c, interrupts on virtio-gpio), e.g. to test a kernel driver."""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path
from typing import Any

from bmg160_emu import limits
from bmg160_emu.commands._chip_options import add_chip_options, chips_from_args
from bmg160_emu.commands._common import Subparsers, add_command_parser, bounded_option

EPILOG = """\
examples:
  bmg160-emu kernel prepare                       # fetch/build the guest into the cache
  bmg160-emu kernel run --seed 7 -- cat /sys/bus/iio/devices/iio:device0/in_anglvel_x_raw
  bmg160-emu kernel run --engine qemu --true-rate 20 -10 5 -- sh -c 'cat $IIO/name'
  bmg160-emu kernel run --module ./my-driver/ --results out/ -- ./read-test.sh
  bmg160-emu kernel run --no-driver -- i2cget -y '$GUEST_I2C_BUS' 0x68 0x00
  bmg160-emu kernel run --real-time -- 'sleep 1; cat $IIO/in_anglvel_x_raw'

The guest mounts the host's root read-only and runs COMMAND (with /bin/sh -c when it is one
word with spaces) in the current folder; --results DIR is writable inside at the same path
(BMG160_RESULTS). Before COMMAND, the driver (the kernel's bmg160, or --module's) is bound
to every chip with its INT1 line as IRQ; IIO names the first chip's device in $IIO.
On the uml engine the guest runs in virtual time (its clock is the chips': the same seed and
COMMAND give the same values on any host); --real-time runs it against wall time.
Exit status: COMMAND's. Docs: docs/commands/kernel.md, docs/kernel-test.md.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers, "kernel",
        "run a command in a disposable Linux guest with the chips on its I2C bus",
        ("Boot a throw-away Linux guest (user-mode Linux or QEMU) whose kernel reaches the "
         "emulated chips through virtio-i2c (interrupts through virtio-gpio), bind a driver "
         "and run a command in it."),
        EPILOG)
    actions = parser.add_subparsers(dest="action", metavar="ACTION")
    prepare = actions.add_parser(
        "prepare", help="fetch and build the guest into the cache; say what is missing",
        description="Fetch Debian's kernel packages and build the guest's pieces into the "
                    "cache ($BMG160_EMU_CACHE or ~/.cache/bmg160-emu), with progress.")
    prepare.add_argument("--engine", default=None, metavar="NAME",
                         help="the engine to prepare (default: every engine)")
    prepare.set_defaults(func=run_prepare)
    run = actions.add_parser(
        "run", help="boot a guest, bind the driver, run COMMAND, return its status",
        description="Boot a guest with the chips on virtio-i2c, bind the driver, run "
                    "COMMAND and return its exit status and output.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("--engine", default=None, metavar="NAME",
                     help="uml or qemu (default: the first that is ready)")
    run.add_argument("--module", type=Path, action="append", default=[], metavar="PATH",
                     help="the driver to test: a .ko, or a source folder with a Kbuild file "
                          "built against the guest kernel's headers (repeatable, loaded in "
                          "dependency order)")
    run.add_argument("--driver", default=None, metavar="NAME",
                     help="the I2C device name to bind (default: bmg160, or the first name "
                          "in --module's id table)")
    run.add_argument("--no-driver", action="store_true",
                     help="bind no driver: the chips answer on the bus only")
    run.add_argument("--route", choices=("virtio", "stub"), default="virtio",
                     help="virtio (default): the chips on the guest's i2c-virtio adapter, "
                          "INT1 on virtio-gpio; stub: in the guest kernel's i2c-stub memory, "
                          "kept by bmg160-emu's adapter inside the guest (no IRQ)")
    run.add_argument("--no-irq", action="store_true",
                     help="bind through new_device, without the INT1 line as IRQ")
    run.add_argument("--real-time", action="store_true",
                     help="run the guest against wall time (default on uml: virtual time, the "
                          "guest's clock is the chips'; qemu always runs in real time)")
    run.add_argument("--results", type=Path, default=None, metavar="DIR",
                     help="a folder COMMAND may write (created; default: a temporary one, "
                          "removed afterwards)")
    run.add_argument("--timeout", type=bounded_option(limits.GUEST_TIMEOUT_S), default=600.0, metavar="SECONDS",
                     help="give up on COMMAND after this long (default 600)")
    run.add_argument("--console", type=Path, default=None, metavar="FILE",
                     help="write the guest's console (kernel messages) to FILE")
    add_chip_options(run, realtime=False)
    run.add_argument("program", nargs=argparse.REMAINDER, metavar="PROGRAM",
                     help="-- COMMAND ARGS...")
    run.set_defaults(func=run_command)

    def usage(_args: argparse.Namespace) -> int:
        parser.print_help()
        return 2

    parser.set_defaults(func=usage)


def _progress(line: str) -> None:
    print(f"bmg160-emu kernel: {line}", file=sys.stderr, flush=True)


def run_prepare(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.linux.guest.engine import EngineError, engines

    available = engines()
    if args.engine is not None and args.engine not in available:
        raise CommandError(f"--engine {args.engine}: unknown (have: {', '.join(available)})")
    ready = []
    for name, engine in available.items():
        if args.engine is not None and name != args.engine:
            continue
        failure = None
        try:
            engine.prepare(_progress)
        except EngineError as exc:
            failure = str(exc)
            print(f"bmg160-emu kernel: {name}: {failure}", file=sys.stderr)
        missing = [line for line in engine.missing() if line != failure]
        for line in missing:
            print(f"bmg160-emu kernel: {name}: missing: {line}", file=sys.stderr)
        print(f"{name}: {'ready' if not missing and failure is None else 'not ready'}")
        if not missing and failure is None:
            ready.append(name)
    return 0 if ready else 1


def run_command(args: argparse.Namespace) -> int:
    from bmg160_emu.clock import VirtualClock
    from bmg160_emu.commands._chip_options import configs_from_args, session_seed
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.linux.guest import stub_route
    from bmg160_emu.linux.guest.drivers import bind_failure, bind_ops, driver_name, load_order
    from bmg160_emu.linux.guest.engine import EngineError, choose
    from bmg160_emu.linux.guest.harness import Backend, Guest, GuestDied, temporary_work

    command = args.program[1:] if args.program[:1] == ["--"] else args.program
    if not command:
        raise CommandError("no COMMAND given (bmg160-emu kernel run [options] -- COMMAND)")
    for path in args.module:
        if not path.exists():
            raise CommandError(f"--module {path}: no such file or folder")
    try:
        engine = choose(args.engine)
        kos = [ko for path in args.module for ko in _module(engine, path)]
        modules = load_order(kos)
    except EngineError as exc:
        raise CommandError(str(exc)) from None
    name = args.driver or (driver_name(kos, prefer=["bmg160"]) if kos else "bmg160")
    if not args.no_driver and name is None:
        raise CommandError("--module declares no I2C device name (i2c: alias): give --driver")
    virtual = bool(getattr(engine, "time_travel", False)) and not args.real_time
    stub = args.route == "stub"
    clock: Any = VirtualClock() if virtual else None
    if clock is None and not args.no_irq and not stub:
        from bmg160_emu.linux.guest_pace import GuestPacedClock

        clock = GuestPacedClock()
    args.realtime = not virtual  # a guest kernel on wall time lives in real time
    if stub:  # the chips are built in the guest, from their configs (stub_route)
        configs, seed = configs_from_args(args), session_seed(args)
        try:
            stub_route.describe(configs, seed)
        except ValueError as exc:
            raise CommandError(f"--route stub: {exc}") from None
        chips: dict[int, Any] = {}
        addresses = [c.address for c in configs]
    else:
        # a random seed is said, so a run can be repeated
        chips = chips_from_args(args, clock=clock)
        addresses = sorted(chips)
    work = temporary_work()
    results = args.results
    if results is not None:
        results.mkdir(parents=True, exist_ok=True)
    backend = Backend(chips, work / "s", gpio=True, clock=clock or VirtualClock(),
                      time_travel=virtual)
    guest = Guest(engine, work, backend, modules=modules, results=results)
    board = None if stub else getattr(engine, "board_module", lambda: None)()
    try:
        guest.start()
        bus = stub_route.start(guest, configs, seed) if stub else guest.i2c_bus
        if not args.no_driver and name is not None:
            irq = not (args.no_irq or board is None or stub)
            lines = [backend.line_of(a) for a in addresses] if irq else None
            ops = bind_ops(name, addresses, bus, lines, board,
                           int(guest.facts.get("gpio_base") or 0), kernel_driver=not kos)
            failure = bind_failure(guest.call(ops, timeout_s=120), ops)
            if failure:
                sys.stderr.write(guest.run("dmesg | tail -n 8", check=False).stdout)
                raise CommandError(f"the driver {name!r} did not bind to the chips: {failure}")
        text = command[0] if len(command) == 1 else " ".join(_quote(w) for w in command)
        prefix = (f"GUEST_I2C_BUS={bus}; export GUEST_I2C_BUS\n"
                  f"IIO=$(ls -d /sys/bus/i2c/devices/{bus}-{addresses[0]:04x}/iio:device* "
                  "2>/dev/null | head -n 1); export IIO\n")
        result = guest.run(prefix + text, timeout_s=args.timeout)
        sys.stdout.write(result.stdout)
        sys.stderr.write(result.stderr)
        if stub:
            stub_route.stop(guest)
        return result.returncode
    except (GuestDied, EngineError) as exc:
        raise CommandError(str(exc).splitlines()[0]) from None
    finally:
        console = guest.close()
        if args.console is not None:
            args.console.write_text(console)
        backend.close()
        if results is not None:
            shutil.rmtree(results / ".agent", ignore_errors=True)
        shutil.rmtree(work, ignore_errors=True)


def _module(engine: object, path: Path) -> list[Path]:
    from bmg160_emu.linux.guest.engine import EngineError

    build = getattr(engine, "build_module", None)
    if build is None:
        raise EngineError(f"--module: the {getattr(engine, 'name', '?')} engine cannot load "
                          "modules")
    return list(build(path, _progress))


def _quote(word: str) -> str:
    """Quote a word for the guest's shell, leaving $VAR references to it."""
    import shlex

    return word if word.startswith("$") and word[1:].replace("_", "").isalnum() else shlex.quote(word)

