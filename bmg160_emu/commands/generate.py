"""``bmg160-emu generate``: noise of the three axes from a profile, streamed to .npy or .csv."""

from __future__ import annotations

import argparse
import secrets
import sys
from pathlib import Path

from bmg160_emu.commands._common import Subparsers, add_command_parser
from bmg160_emu.durations import parse_duration

EPILOG = """\
examples:
  bmg160-emu generate --profile paper --rate 200 --duration 2h --seed 1 -o noise.npy
  bmg160-emu generate --profile datasheet --rate 2000 --duration 10min --seed 3 -o noise.csv
  bmg160-emu generate --profile my-gyro.toml --mode physical --duration 1d -o day.npy
  bmg160-emu generate --profile my-gyro.toml --bandwidth 7 --duration 2h -o filtered.npy

The output holds deg/s per axis, constant bias included: .npy is an (n, 3) float64 array;
.csv has a header t_s,x_dps,y_dps,z_dps (sample k at t = (k + 1) / rate) after '#' lines
naming the profile, mode, rate and seed. The record is written in chunks, never held whole
in memory. Durations: 10s, 5min, 2h, 1d, 250ms or plain seconds. .resd is Renode's sensor
data format (angular rate, channel 0; docs/resd.md).

--bandwidth CODE (BW register 0x10, 0-7) sets the rate to that code's ODR and passes the
noise through the chip's low-pass for that code (device/lowpass.py: 2nd-order Butterworth
at the code's bandwidth, starting at steady state): the noise as a real sensor's filter
shapes it. identify finds that filter and fits above it (docs/identification.md). The
library equivalent is ChipFilteredNoise below.
"""

CHUNK_SAMPLES = 1 << 18  # samples per generate() call while streaming (6 MB per chunk)


class ChipFilteredNoise:
    """A NoiseGenerator's output through the chip's low-pass of one BW code (0-7).

    ``generate(n)`` returns the next n samples (n, 3) in deg/s, chunk invariant in value to
    rounding (the filter state is carried between calls). The rate is the code's ODR.
    """

    def __init__(self, profile="paper", bandwidth_code: int = 7, seed=None,
                 mode: str = "physical") -> None:
        from bmg160_emu.device.lowpass import LowPass
        from bmg160_emu.device.spec_choices import BANDWIDTHS
        from bmg160_emu.noise import NoiseGenerator

        if isinstance(bandwidth_code, bool) or bandwidth_code not in BANDWIDTHS:
            codes = ", ".join(f"{c} ({o} Hz ODR, {b:g} Hz)" for c, (o, b) in BANDWIDTHS.items())
            raise ValueError(f"unknown BW code {bandwidth_code!r}: use one of {codes}")
        odr, bandwidth = BANDWIDTHS[bandwidth_code]
        self.bandwidth_code = bandwidth_code
        self.bandwidth_hz = float(bandwidth)
        self.generator = NoiseGenerator(profile, rate_hz=float(odr), seed=seed, mode=mode)
        self._filter = LowPass(float(odr), float(bandwidth))

    @property
    def rate_hz(self) -> float:
        return self.generator.rate_hz

    @property
    def profile(self):
        return self.generator.profile

    @property
    def mode(self) -> str:
        return self.generator.mode

    def generate(self, n: int):
        block = self.generator.generate(n)
        if block.shape[0] == 0:
            return block
        if not self._filter.started:
            self._filter.restart(block[0])  # at steady state: a powered sensor
        out, self._filter.state = self._filter.run(block)
        return out


def register(subparsers: Subparsers) -> None:
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
        default=None,
        metavar="HZ",
        help="output data rate: 100, 200, 400, 1000 or 2000 Hz (default 200)",
    )
    parser.add_argument(
        "--duration", required=True, metavar="TIME",
        help="simulated time: 10s, 5min, 2h, 1d, or seconds (positive)",
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
        "--bandwidth",
        type=int,
        default=None,
        metavar="CODE",
        help="BW code 0-7: the code's ODR, and the noise through the chip's low-pass for it",
    )
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="OUT.npy, OUT.csv or OUT.resd (Renode)"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.io.atomic import OutputError, atomic_path, check_free_space, check_writable
    from bmg160_emu.io.rate_stream import RateStreamWriter
    from bmg160_emu.noise import NoiseGenerator

    args.rate_given = args.rate is not None
    if args.rate is None:
        args.rate = 200.0

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
    except ValueError as exc:
        raise CommandError(f"--duration: {exc}") from None
    gen: ChipFilteredNoise | NoiseGenerator
    try:
        if args.bandwidth is not None:
            gen = ChipFilteredNoise(args.profile, args.bandwidth, seed=args.seed, mode=args.mode)
            if args.rate_given and args.rate != gen.rate_hz:
                raise CommandError(
                    f"--rate {args.rate:g} Hz disagrees with --bandwidth {args.bandwidth} "
                    f"(ODR {gen.rate_hz:g} Hz): give one of them"
                )
        else:
            gen = NoiseGenerator(args.profile, rate_hz=args.rate, seed=args.seed, mode=args.mode)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    total = round(duration * gen.rate_hz)
    if total < 1:
        raise CommandError(f"duration {args.duration!r} is shorter than one sample period")
    header = (
        f"bmg160-emu generate: profile={gen.profile.name} mode={gen.mode} "
        f"rate_hz={gen.rate_hz:g} seed={args.seed} samples={total}"
        + (f" bandwidth_code={args.bandwidth}" if args.bandwidth is not None else "")
    )
    if chosen_seed:
        print(f"bmg160-emu generate: seed {args.seed} (random; --seed {args.seed} repeats it)",
              file=sys.stderr)
    try:  # before the work: a bad path, or a disk without room (a "1e9d" run streamed GBs)
        check_writable(args.output)
        check_free_space(args.output, RateStreamWriter.size_bytes(suffix, total))
    except OutputError as exc:
        raise CommandError(str(exc)) from None
    bar = _progress(total)
    stopped: KeyboardInterrupt | None = None
    try:
        # under a temporary name: complete, or (interrupted) an honest shorter record
        with atomic_path(args.output) as partial, open(partial, "w+b") as handle:
            if suffix == ".resd":  # Renode Sensor Data, angular rate channel 0 (docs/resd.md)
                from bmg160_emu.io.resd import ResdFormatError, ResdWriter

                try:  # the block states its count up front: an interruption rewrites it
                    start_s = 1.0 / gen.rate_hz  # sample k at (k + 1) / rate, as in the CSV
                    resd = ResdWriter(handle, rate_hz=gen.rate_hz, samples=total,
                                      start_s=start_s)
                    try:
                        for _, block in _chunks(gen, total, bar):
                            resd.write_dps(block)
                    except KeyboardInterrupt as exc:
                        stopped = exc
                        resd.end_short()
                    resd.close()
                except ResdFormatError as exc:
                    raise CommandError(f"{args.output}: {exc}") from None
                written = resd.written
            else:
                writer = RateStreamWriter(handle, suffix, total, gen.rate_hz, [header])
                try:
                    for start, block in _chunks(gen, total, bar):
                        writer.write(start, block)
                except KeyboardInterrupt as exc:
                    stopped = exc
                    writer.end_short(f"interrupted after {writer.samples} of {total} samples")
                written = writer.samples
    except OSError as exc:
        raise CommandError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    finally:
        if bar is not None:
            bar.close()
    if stopped is not None:
        name = getattr(stopped, "signal_name", "SIGINT")
        print(f"bmg160-emu generate: interrupted by {name} after {written:,} of "
              f"{total:,} samples; {args.output} holds those {written:,} "
              f"(its header says so)", file=sys.stderr)
        return 143 if name == "SIGTERM" else 130
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
