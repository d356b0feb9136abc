"""``bmg160-emu vhost-user-i2c``: serve the emulated chips to a QEMU guest's kernel (virtio)."""

from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

from bmg160_emu import limits
from bmg160_emu.commands._chip_options import add_chip_options, chips_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_bus_option,
    add_command_parser,
    add_file_option,
    duration_seconds,
)

EPILOG = """\
example (the socket directory is created 0700 if missing):
  bmg160-emu vhost-user-i2c --socket ~/.cache/bmg160-vu/i2c.sock \\
      --gpio-socket ~/.cache/bmg160-vu/gpio.sock --seed 7 --true-rate 20 -10 5 &
  qemu-system-x86_64 ... \\
      -object memory-backend-memfd,id=mem,size=1024M,share=on -machine memory-backend=mem \\
      -chardev socket,id=vi2c,path=$HOME/.cache/bmg160-vu/i2c.sock \\
      -device vhost-user-i2c-pci,chardev=vi2c \\
      -chardev socket,id=vgpio,path=$HOME/.cache/bmg160-vu/gpio.sock \\
      -device vhost-user-gpio-pci,chardev=vgpio

In the guest, the i2c-virtio adapter carries every transfer to the model as it is made; the
GPIO controller's lines 2i and 2i+1 are INT1 and INT2 of the i-th chip (by address).
The back end runs in real time until interrupted (or --duration has passed) and serves a
new QEMU after the previous one went away. Docs: docs/virtio-i2c.md.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "vhost-user-i2c",
        "serve the emulated chips to a QEMU guest kernel as virtio-i2c (and virtio-gpio)",
        (
            "A vhost-user back end for QEMU's vhost-user-i2c-pci device, and optionally "
            "vhost-user-gpio-pci for the INT1/INT2 lines: the guest kernel's i2c-virtio "
            "adapter and drivers (bmg160_i2c) talk to the emulated BMG160 chips."
        ),
        EPILOG,
    )
    parser.add_argument("--socket", type=Path, required=True, metavar="PATH",
                        help="UNIX socket QEMU connects to for virtio-i2c")
    parser.add_argument("--gpio-socket", type=Path, default=None, metavar="PATH",
                        help="UNIX socket for virtio-gpio: the chips' INT1/INT2 lines")
    add_bus_option(parser, "bus number recorded in the log and trace (default 0)", default=0)
    parser.add_argument("--duration", type=duration_seconds, default=None, metavar="TIME",
                        help="stop after this long: 30s, 5min, or seconds (default: run until interrupted)")
    add_file_option(parser, "--trace", "OUT.jsonl",
                    "record every transaction as a JSON Lines trace (bmg160-emu trace FILE)")
    add_file_option(parser, "--log", "FILE", "write the transaction log to FILE at exit")
    add_file_option(parser, "--stats", "FILE",
                    "write request counts, time in the model and interrupts as JSON at exit")
    add_file_option(parser, "--ready-file", "FILE",
                    "create FILE once the sockets listen (start QEMU after it appears)")
    add_file_option(parser, "--true-rate-file", "FILE",
                    "read 'X Y Z' deg/s from FILE whenever it changes and make it the true "
                    "rate of every chip (drives events from a script)")
    parser.add_argument(
        "--pace", choices=("guest", "wall"), default="guest",
        help="guest (default): the chips' time waits, just before a chip's next sample, "
             "for the driver to read the last one whose data-ready interrupt it got, then "
             "catches up with wall time, so a guest slowed by its host loses no sample; "
             "wall: the chips run on wall time whatever the guest does (also without "
             "--gpio-socket: pacing follows the data-ready interrupts)")
    parser.add_argument("--verbose", action="store_true", help="log vhost-user messages")
    add_chip_options(parser)
    parser.set_defaults(func=run)


def read_true_rate(path: Path) -> tuple[float, float, float] | None:
    """The ``X Y Z`` deg/s a --true-rate-file holds (None while it is empty: ``echo ... >
    FILE`` truncates before it writes); ``ValueError`` with one line naming the file for text
    that is not UTF-8, not three numbers, or numbers out of range (limits.RATE_DPS)."""
    data = path.read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    fields = text.split()
    if not fields:
        return None
    if len(fields) != 3:
        raise ValueError(f"{path}: expected three numbers X Y Z in deg/s, found {len(fields)} "
                         "fields")
    x, y, z = (limits.RATE_DPS.parse(v, str(path)) for v in fields)
    return x, y, z


class _RateFile:
    """A poller that applies the true rate written to a file (checked every 50 ms). A bad
    file at start is refused (``run``); a bad value written later is logged on stderr and the
    last good rate kept: a session is never ended by the file that drives it."""

    def __init__(self, path: Path, chips: dict[int, Any]) -> None:
        self.path = path
        self.chips = chips
        self.stamp: float | None = None
        self.changes: list[dict[str, Any]] = []

    def __call__(self, now_s: float) -> float:
        try:
            stamp = self.path.stat().st_mtime_ns
        except OSError:
            return now_s + 0.05
        if stamp != self.stamp:
            try:
                rate = read_true_rate(self.path)
            except OSError:
                return now_s + 0.05
            except ValueError as exc:
                self.stamp = stamp
                print(f"bmg160-emu vhost-user-i2c: {exc}; true rate unchanged", file=sys.stderr)
                return now_s + 0.05
            if rate is None:
                return now_s + 0.05  # caught between truncation and write: look again
            self.stamp = stamp
            if self.changes and self.changes[-1]["true_rate_dps"] == list(rate):
                # the same rate rewritten (or the write's second time stamp): no change
                return now_s + 0.05
            for chip in self.chips.values():
                chip.set_true_rate(rate)
            first = next(iter(self.chips.values()))
            self.changes.append({"time_s": first.time, "true_rate_dps": list(rate)})
        return now_s + 0.05


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.commands._chip_options import close_trace
    from bmg160_emu.commands._common import CommandError, check_writable
    from bmg160_emu.io.atomic import held_signals
    from bmg160_emu.linux.vhost_user_server import Server, SocketPathError
    from bmg160_emu.linux.virtio_gpio import VirtioGPIODevice
    from bmg160_emu.linux.virtio_i2c import VirtioI2CDevice

    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format="bmg160-emu vhost-user-i2c: %(message)s")
    if args.duration is not None and args.duration <= 0:
        raise CommandError("--duration must be > 0")
    if args.true_rate_file is not None and args.true_rate_file.exists():
        try:  # a bad file is refused before serving; a bad value written later is logged
            read_true_rate(args.true_rate_file)
        except OSError as exc:
            raise CommandError(f"cannot read {args.true_rate_file}: {exc.strerror}") from None
        except ValueError as exc:
            raise CommandError(str(exc)) from None
    for path in (args.stats, args.log):
        if path is not None:  # checked now, written whole at the end: an existing file is
            check_writable(path)  # kept as it was if the back end never serves (issue 24)
    args.realtime = True  # a guest kernel lives in real time
    clock = None
    if args.pace == "guest" and args.gpio_socket is not None:  # pacing needs the interrupts
        from bmg160_emu.linux.guest_pace import GuestPacedClock

        clock = GuestPacedClock()
    chips = chips_from_args(args, clock=clock)
    bus = I2CBus(args.bus, chips)
    i2c = VirtioI2CDevice(bus)
    gpio = (VirtioGPIODevice(chips, i2c.rate_reads, clock, i2c.guest_took_rate_read)
            if args.gpio_socket is not None else None)
    writer = None
    if args.trace is not None:
        from bmg160_emu.commands._chip_options import trace_writer_from_args
        from bmg160_emu.io.trace import TraceWriter

        writer = trace_writer_from_args(args)
        # written after the guest has its answer (i2c.after_transfer), not inside the
        # transfer: the JSON line and its flush cost ~10 us a transaction
        pending: list[Any] = []
        bus.log.sinks.append(pending.append)

        def write_pending(writer: TraceWriter = writer) -> None:
            writer.write_all(pending)
            pending.clear()

        i2c.after_transfer.append(write_pending)
    server = Server()
    rate_file = None
    try:
        try:
            server.add(os.fspath(args.socket), i2c)
            if gpio is not None:
                server.add(os.fspath(args.gpio_socket), gpio)
        except SocketPathError as exc:
            raise CommandError(str(exc)) from None
        except OSError as exc:
            raise CommandError(f"cannot listen on {exc.filename or args.socket}: "
                               f"{exc.strerror}") from None
        if gpio is not None:
            server.pollers.append(gpio.poll)
            gpio.wake = lambda at_s: server.schedule(gpio.poll, at_s)
            i2c.after_transfer.insert(0, gpio.after_transfer)  # before the trace
        if args.true_rate_file is not None:
            rate_file = _RateFile(args.true_rate_file, chips)
            server.pollers.append(rate_file)
        signal.signal(signal.SIGTERM, lambda *_: server.stop())
        if args.ready_file is not None:
            args.ready_file.write_text("ready\n")
        started = time.monotonic()
        try:
            server.run(args.duration)
        except KeyboardInterrupt:
            pass
        elapsed = time.monotonic() - started
    finally:
        server.close()
        if writer is not None:
            write_pending()
            close_trace(writer, args.trace)  # complete after a stop by signal or --duration
    with held_signals():  # a second signal waits until the log and the stats are whole
        _write_outputs(args, bus, i2c, gpio, clock, rate_file, chips, elapsed)
    print(f"bmg160-emu vhost-user-i2c: {i2c.stats.requests} requests in "
          f"{i2c.stats.transfers} transfers", file=sys.stderr)
    return 0


def _write_outputs(args: argparse.Namespace, bus: Any, i2c: Any, gpio: Any, clock: Any,
                   rate_file: Any, chips: Any, elapsed: float) -> None:
    """--log and --stats, each whole or not at all (io.atomic); a write error is one line."""
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.io.atomic import atomic_open

    texts = {}
    if args.log is not None:
        texts[args.log] = str(bus.log) + os.linesep
    if args.stats is not None:
        report = {"elapsed_s": round(elapsed, 3), "i2c": i2c.stats.as_dict(),
                  "gpio": gpio.line_summary() if gpio is not None else [],
                  "stale_data_ready_edges": gpio.stale_edges if gpio is not None else 0,
                  "pace": args.pace if clock is not None else "wall",
                  "paced": ({"held_samples": gpio.held_samples, "given_up": gpio.given_up,
                             "max_lag_s": round(clock.max_lag_ns / 1e9, 6),
                             "final_lag_s": round(clock.lag_s, 6)}
                            if clock is not None and gpio is not None else None),
                  "true_rate_changes": rate_file.changes if rate_file else [],
                  "final": {f"0x{a:02x}": {"odr_hz": c.odr_hz, "power_mode": c.power_mode,
                                           "registers": c.dump().hex()}
                            for a, c in chips.items()}}
        texts[args.stats] = json.dumps(report, indent=1) + "\n"
    for path, text in texts.items():
        try:
            with atomic_open(path, "w", encoding="utf-8") as handle:
                handle.write(text)
        except OSError as exc:
            raise CommandError(f"cannot write {path}: {exc.strerror or exc}") from None
