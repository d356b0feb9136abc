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

The guest mounts the host's root read-only and runs COMMAND (with /bin/sh -c when it is one
word with spaces) in the current folder; --results DIR is writable inside at the same path
(BMG160_RESULTS). Before COMMAND, the driver (the kernel's bmg160, or --module's) is bound
to every chip with its INT1 line as IRQ; IIO names the first chip's device in $IIO.
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
    run.add_argument("--results", type=Path, default=None, metavar="DIR",
                     help="a folder COMMAND may write (created; default: a temporary one, "
                          "removed afterwards)")
    run.add_argument("--timeout", type=bounded_option(limits.GUEST_TIMEOUT_S), default=600.0, metavar="SECONDS",
                     help="give up on COMMAND after this long (default 600)")
    run.add_argument("--console", type=Path, default=None, metavar="FILE",
                     help="write the guest's console (kernel messages) to FILE")
    add_chip_options(run, realtime=False)
    run.add_argument("program", nargs=argparse.REMAINDER, help="-- COMMAND ARGS...")
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
    status = 0
    for name, engine in available.items():
        if args.engine is not None and name != args.engine:
            continue
        try:
            engine.prepare(_progress)
        except EngineError as exc:
            print(f"bmg160-emu kernel: {name}: {exc}", file=sys.stderr)
        missing = engine.missing()
        for line in missing:
            print(f"bmg160-emu kernel: {name}: missing: {line}", file=sys.stderr)
        print(f"{name}: {'ready' if not missing else 'not ready'}")
        status = status or (1 if missing and args.engine is not None else 0)
    return status


def run_command(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.linux.guest.drivers import bind_command, driver_name, load_order
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
    args.realtime = True  # a guest kernel lives in real time
    stub = args.route == "stub"
    clock = None
    if not args.no_irq and not stub:
        from bmg160_emu.linux.guest_pace import GuestPacedClock

        clock = GuestPacedClock()
    chips = chips_from_args(args, clock=clock)  # a random seed is said, so a run can be repeated
    work = temporary_work()
    results = args.results
    if results is not None:
        results.mkdir(parents=True, exist_ok=True)
    backend = None if stub else Backend(chips, work / "s", gpio=True, clock=clock)
    guest = Guest(engine, work, backend, modules=modules, results=results)
    board = None if stub else getattr(engine, "board_module", lambda: None)()
    addresses = sorted(chips)
    prefix = ""
    try:
        guest.start()
        if stub:
            prefix = _start_stub(guest, args, addresses, work)
        if not args.no_driver and name is not None:
            lines = (None if args.no_irq or board is None or backend is None
                     else [backend.line_of(a) for a in addresses])
            bound = guest.run(prefix + bind_command(name, addresses, lines, board,
                                                    kernel_driver=not kos), timeout_s=60)
            if bound.returncode:
                sys.stderr.write(bound.stdout + bound.stderr)
                raise CommandError(f"the driver {name!r} did not bind to the chips")
        text = command[0] if len(command) == 1 else " ".join(_quote(w) for w in command)
        iio = (f"IIO=$(ls -d /sys/bus/i2c/devices/$GUEST_I2C_BUS-{addresses[0]:04x}"
               "/iio:device* 2>/dev/null | head -n 1); export IIO\n")
        result = guest.run(prefix + iio + text, timeout_s=args.timeout)
        sys.stdout.write(result.stdout)
        sys.stderr.write(result.stderr)
        if stub:
            guest.run(f"kill -TERM $(cat {guest.agent_dir}/stub.pid) 2>/dev/null", check=False)
        return result.returncode
    except GuestDied as exc:
        raise CommandError(str(exc).splitlines()[0]) from None
    finally:
        console = guest.close()
        if args.console is not None:
            args.console.write_text(console)
        if backend is not None:
            backend.close()
        if results is not None:
            shutil.rmtree(results / ".agent", ignore_errors=True)
        shutil.rmtree(work, ignore_errors=True)


def _start_stub(guest: Any, args: argparse.Namespace, addresses: list[int], work: Path) -> str:
    """Load i2c-stub with the chips' addresses and start the adapter in the guest; the
    shell prefix that names its bus for later commands."""
    import pickle

    from bmg160_emu.commands._common import CommandError

    options = work / "chips.pickle"
    options.write_bytes(pickle.dumps(argparse.Namespace(
        **{k: v for k, v in vars(args).items() if k != "func"})))
    load = guest.run(
        'm="modprobe ${GUEST_ROOT:+-d $GUEST_ROOT}"\n'
        f"$m i2c-stub chip_addr={','.join(f'0x{a:02x}' for a in addresses)} && $m i2c-dev "
        "|| exit 1\n"
        "for d in /sys/bus/i2c/devices/i2c-*; do\n"
        '  grep -q "SMBus stub" "$d/name" 2>/dev/null && echo "${d##*/i2c-}"\n'
        "done", timeout_s=60)
    bus = load.stdout.split()
    if load.returncode or not bus:
        raise CommandError(f"i2c-stub did not load in the guest: {load.stderr.strip()}")
    prefix = f"GUEST_I2C_BUS={bus[0]}; export GUEST_I2C_BUS\n"
    run = guest.agent_dir  # writable in the guest (the host's /tmp is not)
    started = guest.run(
        prefix + f'"$BMG160_PY" -m bmg160_emu.commands._kernel_stub {options} $GUEST_I2C_BUS '
        f"{run}/stub.ready > {run}/stub.log 2>&1 &\necho $! > {run}/stub.pid\n"
        f"i=0; while [ ! -e {run}/stub.ready ] && [ $i -lt 1200 ] && kill -0 $! 2>/dev/null; "
        "do sleep 0.1; i=$((i + 1)); done\n"
        f"[ -e {run}/stub.ready ] || {{ cat {run}/stub.log >&2; exit 1; }}", timeout_s=180)
    if started.returncode:
        raise CommandError(f"the i2c-stub adapter did not start in the guest: "
                           f"{started.stderr.strip().splitlines()[-1:]}")
    return prefix


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

