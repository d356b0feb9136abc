"""``bmg160-emu serve``: the chips behind a socket any simulator can speak to."""

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

from bmg160_emu.commands._chip_options import add_chip_options, configs_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_command_parser,
    add_file_option,
    duration_seconds,
)

EPILOG = """\
examples (the socket directory is created 0700 if missing):
  bmg160-emu serve --socket ~/.cache/bmg160-emu/serve.sock --seed 7 --true-rate 20 -10 5 &
  ./build/zephyr/zephyr.exe --no-rt --bmg160-emu=$HOME/.cache/bmg160-emu/serve.sock
  bmg160-emu serve --socket /tmp/me/s.sock --part bmi088_gyro --device bmi088_accel@0x18 \\
      --trace zephyr.jsonl --stats stats.json --ready-file /tmp/me/ready

Each client (a native_sim process, a test bench) gets a board of its own, built from these
options and seed, whose clock follows the time stamps of its requests (--realtime: wall
time, line changes pushed). Chips answer I2C at their address and SPI on chip select i,
the i-th device in address order. Protocol: docs/serve-protocol.md; Zephyr: docs/zephyr.md.
With --trace, the n-th client after the first writes NAME.n.jsonl beside it.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "serve",
        "serve the emulated chips to simulators over a socket (Zephyr native_sim, any client)",
        (
            "Serve emulated chips on a UNIX socket in a small versioned protocol: whole I2C "
            "transfers (i2c_rdwr message lists) and SPI transfers at the simulator's time, "
            "interrupt line levels with the time of their next change, errors as the bus "
            "shows them. The Zephyr module in the repository's zephyr/ folder is a client."
        ),
        EPILOG,
    )
    parser.add_argument("--socket", type=Path, required=True, metavar="PATH",
                        help="UNIX socket the simulators connect to")
    parser.add_argument("--duration", type=duration_seconds, default=None, metavar="TIME",
                        help="stop after this long (wall time): 30s, 5min, or seconds "
                             "(default: run until interrupted)")
    add_file_option(parser, "--trace", "OUT.jsonl",
                    "record every transaction as a JSON Lines trace, one file per client")
    add_file_option(parser, "--log", "FILE", "write every client's transaction log at exit")
    add_file_option(parser, "--stats", "FILE",
                    "write requests, errors, line edges and time served per client as JSON")
    add_file_option(parser, "--ready-file", "FILE",
                    "create FILE once the socket listens (start the simulator after it appears)")
    parser.add_argument("--verbose", action="store_true", help="log every client's comings "
                        "and goings")
    add_chip_options(parser, devices=True)
    parser.set_defaults(func=run)


def trace_path(path: Path, number: int) -> Path:
    """Where client ``number``'s trace goes: the path given for the first, NAME.n.SUFFIX
    beside it for the others."""
    if number == 1:
        return path
    return path.with_name(f"{path.stem}.{number}{path.suffix}")


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.clock import RealTimeClock, VirtualClock
    from bmg160_emu.commands._chip_options import (
        announce_seed,
        header_from_chip_args,
        session_seed,
    )
    from bmg160_emu.commands._common import CommandError, check_writable
    from bmg160_emu.io.atomic import held_signals
    from bmg160_emu.io.trace import TraceWriter
    from bmg160_emu.linux.vhost_user_server import SocketPathError
    from bmg160_emu.serve.server import ServeServer
    from bmg160_emu.serve.session import Board

    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="bmg160-emu serve: %(message)s")
    if args.duration is not None and args.duration <= 0:
        raise CommandError("--duration must be > 0")
    for path in (args.stats, args.log):
        if path is not None:
            check_writable(path)
    configs = configs_from_args(args)
    if any(c.bus not in (None, 0) for c in configs):
        raise CommandError("serve has one I2C bus: drop the :BUS of --device")
    seed = session_seed(args, announce=False)  # told once the socket listens
    realtime = bool(getattr(args, "realtime", False))

    def make_board(_number: int) -> Board:
        clock = RealTimeClock() if realtime else VirtualClock()
        chips: dict[int, Any] = {}
        for config in configs:
            try:
                chips[config.address] = config.build(seed, clock)
            except (ValueError, KeyError, OSError) as exc:
                raise CommandError(str(exc)) from None
        spi = {cs: chips[a] for cs, a in enumerate(sorted(chips))}
        return Board(chips, clock, spi)

    make_board(0)  # a bad option fails now, before anything listens
    writers: dict[int, TraceWriter] = {}
    trace_errors: list[str] = []

    def started(session: Any) -> None:
        if args.trace is None:
            return
        path = trace_path(args.trace, session.number)
        try:
            writer = TraceWriter(path, header_from_chip_args(args))
        except OSError as exc:
            trace_errors.append(f"cannot write {path}: {exc.strerror}")
            return
        writers[session.number] = writer
        session.log.sinks.append(writer)

    def ended(session: Any) -> None:
        writer = writers.pop(session.number, None)
        if writer is not None:
            try:
                writer.close(complete=True)  # every transfer served is in it
            except OSError as exc:
                trace_errors.append(f"cannot write {trace_path(args.trace, session.number)}: "
                                    f"{exc.strerror or exc}")

    server = ServeServer(make_board, realtime=realtime, on_session_start=started,
                         on_session_end=ended)
    started_s = time.monotonic()
    try:
        try:
            server.listen_unix(os.fspath(args.socket))
        except SocketPathError as exc:
            raise CommandError(str(exc)) from None
        except OSError as exc:
            raise CommandError(f"cannot listen on {args.socket}: {exc.strerror}") from None
        signal.signal(signal.SIGTERM, lambda *_: server.stop())
        announce_seed(args)
        if args.ready_file is not None:
            args.ready_file.write_text("ready\n")
        try:
            server.run(args.duration)
        except KeyboardInterrupt:
            pass
    finally:
        server.close()
    elapsed = time.monotonic() - started_s
    with held_signals():  # a second signal waits until the log and the stats are whole
        _write_outputs(args, server, elapsed)
    for line in trace_errors:
        print(f"bmg160-emu serve: {line}", file=sys.stderr)
    requests = sum(sum(s.stats.requests.values()) for s in server.sessions)
    print(f"bmg160-emu serve: {len(server.sessions)} client(s), {requests} requests",
          file=sys.stderr)
    return 1 if trace_errors else 0


def _write_outputs(args: argparse.Namespace, server: Any, elapsed: float) -> None:
    """--log and --stats, each whole or not at all (io.atomic); a write error is one line."""
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.io.atomic import atomic_open

    texts = {}
    if args.log is not None:
        parts = [f"# client {s.number} ({s.client_name or 'unnamed'})\n{s.log}\n"
                 for s in server.sessions]
        texts[args.log] = "".join(parts)
    if args.stats is not None:
        report = {"elapsed_s": round(elapsed, 3), "seed": args.seed, **server.stats(),
                  "final": [{f"0x{a:02x}": c.dump().hex() for a, c in s.board.chips.items()}
                            for s in server.sessions]}
        texts[args.stats] = json.dumps(report, indent=1) + "\n"
    for path, text in texts.items():
        try:
            with atomic_open(path, "w", encoding="utf-8") as handle:
                handle.write(text)
        except OSError as exc:
            raise CommandError(f"cannot write {path}: {exc.strerror or exc}") from None
