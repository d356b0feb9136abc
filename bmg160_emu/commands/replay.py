"""``bmg160-emu replay``: a recording of real data as the chip's output."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bmg160_emu import limits
from bmg160_emu.commands._chip_options import RANGE_CODE_BY_DPS, add_chip_options, chips_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_command_parser,
    add_progress_options,
    bounded_option,
    check_writable,
    run_script_file,
)

EPILOG = """\
examples:
  bmg160-emu replay flight.csv --bandwidth 4 -o through-chip.csv
  bmg160-emu replay bench.npz --unit counts --data-range 500 --script driver-check.script
  bmg160-emu record --duration 30s --rate 200 -o a.csv && \\
    bmg160-emu replay a.csv --unit counts --bandwidth 6 -o b.csv     # same samples

DATA is CSV (a time column and x, y, z; a header row names them, or exactly 4 columns
t, x, y, z) or NPZ (t_s and rate_dps or counts, or x, y, z arrays). Each output sample of
the chip carries the recorded rate at that moment, resampled to the chip's ODR (linear
interpolation, or the mean over each output period when the data are at least twice as
fast; docs/replay.md). Gaps, time going backwards, wrong column counts and unit mismatches
are errors naming the line.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "replay",
        "play a recording (CSV/NPZ) through the chip's registers",
        "Make a recording of real gyro data the emulated chip's output, then "
        "record what a driver reads (-o) or run a register script against it (--script).",
        EPILOG,
    )
    parser.add_argument("data", type=Path, metavar="DATA", help="recording (.csv or .npz)")
    parser.add_argument("--unit", choices=("dps", "counts"), default="dps",
                        help="unit of the x, y, z data (default: dps)")
    parser.add_argument(
        "--data-range", type=bounded_option(limits.FULL_SCALE_DPS), default=None, metavar="DPS", choices=sorted(RANGE_CODE_BY_DPS),
        help="for --unit counts without a settings line: the range they were recorded at",
    )
    parser.add_argument("--max-gap-factor", type=bounded_option(limits.GAP_FACTOR), default=3.0, metavar="F",
                        help="a time step over F times the median step is a gap (default 3)")
    parser.add_argument("--loop", action="store_true", help="start over at the end (default: hold)")
    parser.add_argument("-o", "--output", type=Path, default=None, metavar="FILE",
                        help="record the chip's output during the replay to OUT.csv, .npz or "
                        ".resd")
    parser.add_argument("--script", type=Path, default=None, metavar="FILE",
                        help="run a register script instead")
    add_progress_options(parser)
    add_chip_options(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.device import spec_choices
    from bmg160_emu.durations import check_simulated_time
    from bmg160_emu.io.errors import FormatError
    from bmg160_emu.io.formats import format_for
    from bmg160_emu.io.rate_table import RateFileError
    from bmg160_emu.io.replay_data import load_replay_data
    from bmg160_emu.session.rate_replay import ReplaySource

    if (args.output is None) == (args.script is None):
        raise CommandError("give -o OUT (record the chip's output) or --script FILE, one of them")
    if args.output is not None:
        try:  # the registry's formats of a recording (io/recording.py)
            format_for("recording", args.output, writing=True, what="output")
        except FormatError as exc:
            raise CommandError(str(exc)) from None
        check_writable(args.output)
    if not args.max_gap_factor > 1:
        raise CommandError("--max-gap-factor must be greater than 1")
    lsb = None
    if args.data_range is not None:
        table = spec_choices.SENSITIVITY_TABLES[getattr(args, "sensitivity", "binary")]
        lsb = table[RANGE_CODE_BY_DPS[args.data_range]]
    try:
        data = load_replay_data(args.data, args.unit, lsb, args.max_gap_factor)
    except RateFileError as exc:  # the library's parameter, named as this command spells it
        raise CommandError(str(exc).replace("(max_gap_factor)", "(--max-gap-factor)")) from None
    chips = chips_from_args(args, announce=False)  # the data replaces the output: no seed to repeat
    chip = next(iter(chips.values()))
    ReplaySource(data, loop=args.loop).attach(chip)
    if args.output is not None:
        duration = data.duration_s + data.median_step_s
        try:  # checked before recording: a span of 2e8 s asked for 45 GiB
            check_simulated_time(duration, f"{duration:g} s", f"{args.data}: the replay span")
            limits.RECORD_SAMPLES.check(round(duration * chip.odr_hz),
                                        f"{args.data}: a replay of {duration:g} s")
        except ValueError as exc:  # LimitError is one
            raise CommandError(f"{exc} (at {chip.odr_hz:g} Hz)") from None
        return _record_to(args, chip, data)
    return run_script_file(args.script, chips, print, "FAILED ")


def _record_to(args: argparse.Namespace, chip: Any, data: Any) -> int:
    """The chip's output during the replay, recorded to ``path``: whole, or (a signal) the
    samples so far marked interrupted, or nothing before the first sample; written under a
    temporary name with the signals held (io.atomic), so a full disk or a ^C keeps the old
    file (it used to leave a truncated one under the target's name)."""
    from bmg160_emu.commands._common import CommandError, check_memory, progress_for
    from bmg160_emu.io.atomic import held_signals
    from bmg160_emu.io.recording import write_recording
    from bmg160_emu.session.record import RecordingInterrupted, record

    path, source = args.output, args.data

    samples = round((data.duration_s + data.median_step_s) * chip.odr_hz)
    check_memory(samples * limits.RECORD_BYTES_PER_SAMPLE, f"recording {samples:,} samples "
                 f"({limits.RECORD_BYTES_PER_SAMPLE} bytes each until they are written)",
                 "replay a shorter file, or at a lower output data rate")
    stopped: KeyboardInterrupt | None = None
    try:
        with progress_for(args, "replay").stage(samples, "samples") as update:
            rec = record(chip, data.duration_s + data.median_step_s,
                         lambda done, total: update(done))
    except RecordingInterrupted as exc:
        stopped, rec = exc, exc.recording
        if len(rec) == 0:
            exc.kept = f"no sample recorded; {path} not written"  # type: ignore[attr-defined]
            raise
    rec.metadata["replayed"] = str(source)
    rec.true_rate_dps = None  # the truth behind real data is unknown
    try:
        with held_signals():  # complete or not at all (io.recording writes atomically)
            write_recording(rec, path)
    except KeyboardInterrupt as exc:  # held while writing: the file is whole
        stopped = stopped or exc
    except OSError as exc:
        raise CommandError(f"cannot write {path}: {exc.strerror or exc}") from None
    if stopped is not None:
        name = getattr(stopped, "signal_name", "SIGINT")
        what = ("marked interrupted" if rec.metadata.get("interrupted") else "complete")
        print(f"bmg160-emu replay: interrupted by {name}; {path} holds {len(rec):,} samples "
              f"({what})", file=sys.stderr)
        return 143 if name == "SIGTERM" else 130
    print(f"replayed {len(data.t_s)} samples of {source}; recorded {len(rec)} at "
          f"{rec.odr_hz:g} Hz to {path}")
    return 0
