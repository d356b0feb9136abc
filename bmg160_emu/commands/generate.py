"""``bmg160-emu generate``: noise of the three axes from a profile, streamed to .npy or .csv."""

from __future__ import annotations

import argparse
import secrets
import sys
from pathlib import Path

from bmg160_emu import limits
from bmg160_emu.commands._common import (
    Subparsers,
    add_command_parser,
    add_progress_options,
    add_renamed_option,
    bounded_option,
    profile_named,
    progress_for,
)
from bmg160_emu.durations import parse_duration

EPILOG = """\
examples:
  bmg160-emu generate --profile paper --rate 200 --duration 2h --seed 1 -o noise.npy
  bmg160-emu generate --profile datasheet --rate 2000 --duration 10min --seed 3 -o noise.csv
  bmg160-emu generate --profile examples/profiles/my-gyro.toml --duration 1d -o day.npy
  bmg160-emu generate --profile examples/profiles/my-gyro.toml --bandwidth 7 --duration 2h -o filtered.npy
  bmg160-emu generate --profile examples/profiles/imu.yaml --duration 10min -o kalibr.npy

The examples/ paths are in the source tree (git clone); a profile of your own is any TOML
file of that form (docs/noise-engine.md).

The output holds deg/s per axis, constant bias included: .npy is an (n, 3) float64 array;
.csv has a header t_s,x_dps,y_dps,z_dps (sample k at t = (k + 1) / rate) after '#' lines
naming the profile, mode, rate, seed and output stage. The record is written in chunks,
never held whole in memory. Durations: 10s, 5min, 2h, 1d, 250ms or plain seconds. .resd is
Renode's sensor data format (angular rate, channel 0; docs/resd.md).

The noise is the sensing element's, through the sensor's output stage as the profile's
[output] table names it (identify --profile-out writes the filter and the quantization step
it found on a record): a profile without one gives the noise as before. --bandwidth CODE
(BW register 0x10, 0-7) sets the rate to that code's ODR and filters with the chip's
low-pass for that code instead (noise/bandwidths.py: 2nd-order Butterworth at the code's
bandwidth), as a chip at that setting does; --raw leaves the output stage out. Paper mode is
the paper's output-referred recursion: nothing filters it. The library equivalent is
bmg160_emu.noise.sensor_noise.profile_noise, on the same code as the chip's noise.
"""

CHUNK_SAMPLES = 1 << 18  # samples per generate() call while streaming (6 MB per chunk)


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
        "--profile", default="paper", metavar="NAME|FILE",
        help="built-in profile (paper, datasheet), a TOML profile, a Kalibr imu.yaml (.yaml, "
        ".yml) or a MATLAB gyroparams .m file (default paper)"
    )
    parser.add_argument(
        "--rate",
        type=bounded_option(limits.SAMPLE_RATE_HZ),
        default=None,
        metavar="HZ",
        help="output data rate: 100, 200, 400, 1000 or 2000 Hz (default 200)",
    )
    parser.add_argument(
        "--duration", required=True, metavar="TIME",
        help="simulated time: 10s, 5min, 2h, 1d, or seconds (positive)",
    )
    parser.add_argument(
        "--seed", type=bounded_option(limits.SEED), default=None, metavar="N",
        help="noise seed (default: random, chosen, printed and written to a CSV header)",
    )
    parser.add_argument(
        "--noise-mode",
        choices=("physical", "paper"),
        default="physical",
        help="physical: N, B, T, K scaled with the sample period (default); "
        "paper: the paper's recursion (docs/noise-engine.md)",
    )
    add_renamed_option(parser, "--mode", "--noise-mode", dest="noise_mode",
                       choices=("physical", "paper"))
    parser.add_argument(
        "--bandwidth",
        type=bounded_option(limits.BANDWIDTH_CODE),
        default=None,
        metavar="CODE",
        help="BW code 0-7: the code's ODR, and the noise through the chip's low-pass for it "
        "(instead of the profile's own filter)",
    )
    parser.add_argument(
        "--raw",
        action="store_true",
        help="the sensing element's noise alone: the profile's output filter and "
        "quantization ([output]) left out",
    )
    parser.add_argument(
        "-o", "--output", type=Path, required=True, metavar="FILE",
        help="OUT.npy, OUT.csv or OUT.resd (Renode)"
    )
    add_progress_options(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.io.atomic import (
        OutputError,
        atomic_path,
        check_free_space,
        check_writable,
        held_signals,
    )
    from bmg160_emu.io.errors import FormatError
    from bmg160_emu.io.formats import block_writer_for
    from bmg160_emu.io.partial import clear_sidecar, write_sidecar
    from bmg160_emu.noise.profile import ProfileError
    from bmg160_emu.noise.sensor_noise import ProfileNoise, profile_noise

    try:  # the registry's formats of a rate stream (io/rate_stream.py)
        stream = block_writer_for("rate stream", args.output, what="output")
    except FormatError as exc:
        raise CommandError(str(exc)) from None
    chosen_seed = args.seed is None
    if chosen_seed:
        args.seed = secrets.randbits(32)  # a record names its seed: a random run can be repeated
    try:
        duration = parse_duration(args.duration)
    except ValueError as exc:
        raise CommandError(f"--duration: {exc}") from None
    if args.bandwidth is not None and args.noise_mode == "paper":
        raise CommandError("--bandwidth filters the physical mode's noise; paper mode is the "
                           "paper's output-referred recursion (nothing filters it): give --rate")
    if args.bandwidth is not None and args.raw:
        raise CommandError("--raw leaves every filter out: it does not go with --bandwidth")
    gen: ProfileNoise
    try:
        gen = profile_noise(args.profile, args.rate, seed=args.seed, mode=args.noise_mode,
                            bandwidth_code=args.bandwidth, use_output=not args.raw)
    except ProfileError as exc:  # named by the profile as given (issue 35)
        raise CommandError(profile_named(args.profile, str(exc))) from None
    except ValueError as exc:
        text = str(exc)  # a rate the BW code has not is named as the option it came from
        if text.startswith("unsupported output data rate"):  # paper mode (docs/limits.md)
            text = f"rate {args.rate:g} Hz in paper mode: {text}"
        raise CommandError(f"--{text}" if text.startswith("rate ") else text) from None
    for note in gen.notes:  # what of the profile's output stage is left out, and why
        print(f"bmg160-emu generate: note: {note}", file=sys.stderr)
    total = round(duration * gen.rate_hz)
    if total < 1:
        raise CommandError(f"duration {args.duration!r} is shorter than one sample period")
    header = (
        f"bmg160-emu generate: profile={gen.profile.name} mode={gen.mode} "
        f"rate_hz={gen.rate_hz:g} seed={args.seed} samples={total}"
        + (f" bandwidth_code={args.bandwidth}" if args.bandwidth is not None else "")
        + (f" output={gen.describe()}" if gen.describe() != "none" else "")
    )
    if chosen_seed:
        print(f"bmg160-emu generate: seed {args.seed} (random; --seed {args.seed} repeats it)",
              file=sys.stderr)
    try:  # before the work: a bad path, or a disk without room (a "1e9d" run streamed GBs)
        check_writable(args.output)
        check_free_space(args.output, stream.size_bytes(total))
    except OutputError as exc:
        raise CommandError(str(exc)) from None
    progress = progress_for(args, "generate")
    stopped: KeyboardInterrupt | None = None
    try:
        # under a temporary name: complete, or (interrupted) an honest shorter record
        with atomic_path(args.output) as partial, open(partial, "w+b") as handle:
            try:
                writer = stream(handle, total, gen.rate_hz, [header])
                try:
                    for start, block in _chunks(gen, total, progress):
                        writer.write(start, block)
                except KeyboardInterrupt as exc:
                    if writer.samples == 0:  # no sample: no file (it would look valid)
                        exc.kept = f"no sample generated; {args.output} not written"  # type: ignore[attr-defined]
                        raise
                    stopped = exc
                    note = f"interrupted after {writer.samples} of {total} samples"
                    with held_signals():  # a second signal must not cut the honest file
                        writer.end_short(note)
                        if not writer.notes_inside:  # RESD: said beside the file
                            write_sidecar(args.output, note)
            except FormatError as exc:
                raise CommandError(f"{args.output}: {exc}") from None
            written = writer.samples
            if stopped is None:
                clear_sidecar(args.output)  # an earlier cut run's mark
    except OSError as exc:
        raise CommandError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    if stopped is not None:
        name = getattr(stopped, "signal_name", "SIGINT")
        print(f"bmg160-emu generate: interrupted by {name} after {written:,} of "
              f"{total:,} samples; {args.output} holds those {written:,}, marked partial",
              file=sys.stderr)
        return 143 if name == "SIGTERM" else 130
    print(f"wrote {args.output}: {written:,} samples x 3 axes, deg/s, at {gen.rate_hz:g} Hz "
          f"({total / gen.rate_hz:g} s); profile {gen.profile.name}, {gen.mode} mode, seed "
          f"{args.seed}" + (f", output stage {gen.describe()}" if gen.describe() != "none" else ""))
    return 0


def _chunks(gen, total: int, progress):
    """The samples in blocks of CHUNK_SAMPLES, the progress told after each."""
    done = 0
    with progress.stage(total, "samples") as update:
        while done < total:
            m = min(CHUNK_SAMPLES, total - done)
            yield done, gen.generate(m)
            done += m
            update(done)
