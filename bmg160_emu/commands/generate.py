"""``bmg160-emu generate``: noise of the three axes from a profile, streamed to .npy or .csv."""

from __future__ import annotations

import argparse
import secrets
import sys
from pathlib import Path

from bmg160_emu.commands._common import add_command_parser
from bmg160_emu.durations import parse_duration

EPILOG = """\
examples:
  bmg160-emu generate --profile paper --rate 200 --duration 2h --seed 1 -o noise.npy
  bmg160-emu generate --profile datasheet --rate 2000 --duration 10min --seed 3 -o noise.csv
  bmg160-emu generate --profile my-gyro.toml --mode physical --duration 1d -o day.npy

The output holds deg/s per axis, constant bias included: .npy is an (n, 3) float64 array;
.csv has a header t_s,x_dps,y_dps,z_dps (sample k at t = (k + 1) / rate) after '#' lines
naming the profile, mode, rate and seed. The record is written in chunks, never held whole
in memory. Durations: 10s, 5min, 2h, 1d, 250ms or plain seconds. .resd is Renode's sensor
data format (angular rate, channel 0; docs/resd.md).
"""

CHUNK_SAMPLES = 1 << 18  # samples per generate() call while streaming (6 MB per chunk)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = add_command_parser(
        subparsers,
        "generate",
        "generate gyroscope noise (N, B, T, K per axis) to .npy or .csv",
        "Generate the noise of the three BMG160 axes from a noise profile, "
        "seeded and streamed to a file.",
        EPILOG,
    )
    parser.add_argument(
        "--profile", default="paper", help="built-in profile (paper, datasheet) or a TOML file"
    )
    parser.add_argument(
        "--rate",
        type=float,
        default=200.0,
        metavar="HZ",
        help="output data rate: 100, 200, 400, 1000 or 2000 Hz (default 200)",
    )
    parser.add_argument(
        "--duration", required=True, metavar="TIME", help="simulated time: 10s, 5min, 2h, 1d"
    )
    parser.add_argument(
        "--seed", type=int, default=None,
        help="noise seed (default: random, chosen, printed and written to a CSV header)",
    )
    parser.add_argument(
        "--mode",
        choices=("physical", "paper"),
        default="physical",
        help="physical: N, B, T, K scaled with the sample period (default); "
        "paper: the paper's recursion (docs/noise-engine.md)",
    )
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="OUT.npy, OUT.csv or OUT.resd (Renode)"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.io.rates import RateStreamWriter
    from bmg160_emu.noise import NoiseGenerator

    suffix = args.output.suffix.lower()
    if suffix not in (".npy", ".csv", ".resd"):
        raise CommandError(f"output must end in .npy, .csv or .resd, not {args.output.name!r}")
    chosen_seed = args.seed is None
    if chosen_seed:
        args.seed = secrets.randbits(32)  # a record names its seed: a random run can be repeated
    elif args.seed < 0:
        raise CommandError(f"--seed must be a non-negative integer, not {args.seed}")
    try:
        duration = parse_duration(args.duration)
        gen = NoiseGenerator(args.profile, rate_hz=args.rate, seed=args.seed, mode=args.mode)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    total = round(duration * gen.rate_hz)
    if total < 1:
        raise CommandError(f"duration {args.duration!r} is shorter than one sample period")
    header = (
        f"bmg160-emu generate: profile={gen.profile.name} mode={gen.mode} "
        f"rate_hz={gen.rate_hz:g} seed={args.seed} samples={total}"
    )
    if chosen_seed:
        print(f"bmg160-emu generate: seed {args.seed} (random; --seed {args.seed} repeats it)",
              file=sys.stderr)
    bar = _progress(total)
    try:
        with open(args.output, "wb") as handle:
            if suffix == ".resd":  # Renode Sensor Data, angular rate channel 0 (docs/resd.md)
                from bmg160_emu.io.resd import ResdFormatError, ResdWriter

                try:
                    start_s = 1.0 / gen.rate_hz  # sample k at (k + 1) / rate, as in the CSV
                    with ResdWriter(handle, rate_hz=gen.rate_hz, samples=total, start_s=start_s) as w:
                        for _, block in _chunks(gen, total, bar):
                            w.write_dps(block)
                except ResdFormatError as exc:
                    raise CommandError(f"{args.output}: {exc}") from None
            else:
                writer = RateStreamWriter(handle, suffix, total, gen.rate_hz, [header])
                for start, block in _chunks(gen, total, bar):
                    writer.write(start, block)
    except OSError as exc:
        raise CommandError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    finally:
        if bar is not None:
            bar.close()
    return 0


def _progress(total: int):
    if not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="sample", unit_scale=True, file=sys.stderr)


def _chunks(gen, total: int, bar):
    done = 0
    while done < total:
        m = min(CHUNK_SAMPLES, total - done)
        yield done, gen.generate(m)
        done += m
        if bar is not None:
            bar.update(m)
