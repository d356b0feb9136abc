"""``bmg160-emu stub``: keep a kernel i2c-stub chip in step with the model (kernel drivers)."""

from __future__ import annotations

import argparse
import json
import signal
import sys
from collections.abc import Callable
from typing import Any

from bmg160_emu import limits
from bmg160_emu.commands._chip_options import add_chip_options, announce_seed, chips_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_bus_option,
    add_command_parser,
    add_file_option,
    bounded_option,
    duration_seconds,
)

EPILOG = """\
examples (as root, on a machine or VM that can load modules):
  modprobe i2c-stub chip_addr=0x68 && modprobe i2c-dev
  bmg160-emu stub --bus 0 --address 0x68 --seed 7 &
  echo bmg160 0x68 > /sys/bus/i2c/devices/i2c-0/new_device
  (a BMI088 gyro: bmg160-emu stub --bus 0 --device bmi088_gyro@0x68, then
   echo bmi088_gyro 0x68 > .../new_device)
  cat /sys/bus/iio/devices/iio:device0/in_anglvel_x_raw
  bmg160-emu stub --bus 0 --device bma2x2_accel@0x18 &   # a stand-in (registers only), then
  echo bmi055_accel 0x18 > .../new_device                # the kernel's bmc150-accel binds
  bmg160-emu stub --bus 0 --seed 7 --true-rate 20 -10 5 --duration 30s --stats stats.json
  bmg160-emu stub --bus 0 --seed 7 --ready-file /run/bmg160.ready &   # scripts wait for it
  modprobe i2c-stub chip_addr=0x68,0x69    # two chips: one stub process per address
  bmg160-emu stub --bus 0 --address 0x69 --seed 8 &

The adapter runs in real time until interrupted (or --duration has passed), refreshing the
data registers once per output data period (at most --max-refresh-hz) and applying what
the driver writes. Docs: docs/i2c-stub.md.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "stub",
        "serve the emulated chip to kernel drivers through the i2c-stub module",
        (
            "Keep the register memory of a Linux i2c-stub chip in step with the emulated "
            "BMG160, so kernel drivers (the kernel's bmg160 IIO driver) read live data."
        ),
        EPILOG,
    )
    add_bus_option(parser, "number N of the i2c-stub bus /dev/i2c-N", required=True)
    parser.add_argument(
        "--duration", type=duration_seconds, default=None, metavar="TIME",
        help="stop after this long: 30s, 5min, or seconds (default: run until interrupted)",
    )
    add_file_option(
        parser, "--stats", "FILE",
        "write refresh timing (period, jitter, CPU use) and the client writes applied to the "
        "model as JSON to FILE at exit",
    )
    parser.add_argument(
        "--max-refresh-hz", type=bounded_option(limits.REFRESH_HZ), default=None, metavar="HZ",
        help="refresh at most this often even at higher output data rates (default 500)",
    )
    add_file_option(
        parser, "--ready-file", "FILE", "create FILE once the register map is preloaded (for scripts)"
    )
    add_chip_options(parser, realtime=False, devices=True)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.linux.i2c_stub import (
        I2CStubAdapter,
        StubSetupError,
        bound_driver,
        check_stub_bus,
    )

    devices = list(args.devices or [])
    for device in devices:
        if device.bus is not None and device.bus != args.bus:
            raise CommandError(f"--device {device.text}: stub serves bus {args.bus} only")
    addresses = list(dict.fromkeys(args.addresses or ([] if devices else [0x68])))
    addresses += [d.address for d in devices]
    if len(addresses) != 1:
        raise CommandError("stub serves one chip address per process: give --address or "
                           "--device once")
    address = addresses[0]
    try:
        check_stub_bus(args.bus, address)
    except StubSetupError as exc:
        raise CommandError(str(exc)) from None
    stats_file = None
    if args.stats is not None:
        try:  # opened now: a bad path is an error before the adapter runs, not at its end
            stats_file = args.stats.open("w", encoding="utf-8")
        except OSError as exc:
            raise CommandError(f"cannot write {args.stats}: {exc.strerror}") from None
    if devices and devices[0].standin is not None:
        return _run_standin(args, devices[0], stats_file)
    args.realtime = True  # a kernel driver lives in real time
    # --part or the --device part; a chosen seed is printed once the adapter is open, so a
    # setup error stays the one line of output
    chip = chips_from_args(args, announce=False)[address]
    if args.max_refresh_hz is not None and args.max_refresh_hz <= 0:
        raise CommandError("--max-refresh-hz must be > 0")
    adapter = _open(args, lambda: I2CStubAdapter(chip, args.bus, address))
    if args.max_refresh_hz is not None:
        adapter.max_refresh_hz = args.max_refresh_hz
    announce_seed(args)

    def adopt_a_bound_drivers_configuration() -> None:
        driver = bound_driver(args.bus, address)
        if driver is not None:
            adopted = adapter.adopt()
            print(f"bmg160-emu stub: the {driver} driver is bound to 0x{address:02x}: took its "
                  f"configuration from i2c-stub's memory ({len(adopted)} registers differ from "
                  "reset) instead of preloading reset values", file=sys.stderr)

    try:
        _serve(args, adapter, before_preload=adopt_a_bound_drivers_configuration)
    finally:
        adapter.close()
        if stats_file is not None:
            report = {
                "summary": adapter.stats.summary(),
                "events": adapter.events,
                "final": {
                    "odr_hz": chip.odr_hz,
                    "power_mode": chip.power_mode,
                    "registers": chip.dump().hex(),
                },
            }
            with stats_file:
                stats_file.write(json.dumps(report, indent=1) + "\n")
    print(f"bmg160-emu stub: {adapter.stats.summary().get('refreshes', 0):.0f} refreshes",
          file=sys.stderr)
    return 0


def _run_standin(args: argparse.Namespace, device: Any, stats_file: Any) -> int:
    """A stand-in behind i2c-stub: the client's writes applied to it (masks, read-only bits,
    soft reset, power gate) and what it then reads written back (linux/i2c_stub_standin.py)."""
    from bmg160_emu.device.standin import StandinDevice
    from bmg160_emu.linux.i2c_stub_standin import StandinStubAdapter

    standin = StandinDevice(device.standin, device.address)
    adapter = _open(args, lambda: StandinStubAdapter(standin, args.bus, device.address))
    try:
        _serve(args, adapter)
    finally:
        adapter.close()
        if stats_file is not None:
            report = {"standin": standin.name, "polls": adapter.polls, "events": adapter.events,
                      "final": {"registers": standin.dump().hex()}}
            with stats_file:
                stats_file.write(json.dumps(report, indent=1) + "\n")
    print(f"bmg160-emu stub: {standin.name} at 0x{device.address:02x}: {adapter.polls} polls, "
          f"{len(adapter.events)} client writes", file=sys.stderr)
    return 0


def _open(args: argparse.Namespace, make: Callable[[], Any]) -> Any:
    """The adapter on /dev/i2c-BUS, its open errors as one line."""
    from bmg160_emu.commands._common import CommandError

    try:
        return make()
    except PermissionError:
        raise CommandError(f"permission denied on /dev/i2c-{args.bus}: run as root") from None
    except OSError as exc:
        raise CommandError(f"cannot open /dev/i2c-{args.bus}: {exc.strerror}") from None


def _serve(args: argparse.Namespace, adapter: Any,
           before_preload: Callable[[], None] | None = None) -> None:
    """Preload, signal readiness, then keep i2c-stub in step until --duration, SIGINT or
    SIGTERM (both end cleanly)."""
    from bmg160_emu.commands._common import CommandError

    stop: list[bool] = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    try:
        if before_preload is not None:
            before_preload()
        adapter.preload()
        if args.ready_file is not None:
            args.ready_file.write_text("ready\n")
        adapter.run(duration_s=args.duration, should_stop=lambda: bool(stop), preload=False)
    except KeyboardInterrupt:
        pass
    except OSError as exc:
        raise CommandError(f"i2c-stub access failed: {exc}") from None
