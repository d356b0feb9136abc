"""``bmg160-emu record``: what the chip outputs at its ODR, with the true rate beside it."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bmg160_emu import limits
from bmg160_emu.commands._chip_options import add_chip_options, chips_from_args
from bmg160_emu.commands._common import (
    Subparsers,
    add_command_parser,
    add_progress_options,
    bounded_option,
    check_memory,
    check_writable,
    progress_for,
)

EPILOG = """\
examples:
  bmg160-emu record --duration 10min --rate 200 --seed 7 -o static.csv
  bmg160-emu record --duration 1h --range 250 --rate 200 -o static.npz
  bmg160-emu record --truth examples/scenarios/slew.toml --rate 400 -o slew.csv
  bmg160-emu identify static.npz      # N, B, T, K of the recorded output
  bmg160-emu record --duration 1min --rate 200 -o static.resd   # for Renode (docs/resd.md)

Every output sample is read as a driver reads it (one 6-byte burst from RATE_X_LSB after
each new sample); the file holds time, raw counts, deg/s (counts / sensitivity) and the
true body rate. --rate picks the BW code the Linux driver uses for that output data rate
(100->0x07, 200->0x06, 400->0x03, 1000->0x02, 2000->0x01); --bandwidth picks any code.
Without either the chip keeps its reset BW (0x00): 2000 Hz, where generate's default is
200 Hz. Durations: 10min, 30s, 1.5h, 1d, 250ms, or seconds; they must be positive.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "record",
        "record the chip's output at its ODR (counts, deg/s, true rate) to CSV or NPZ",
        "Run an emulated BMG160 for a while and record every output sample as a "
        "driver reads it, beside the true rate it was fed.",
        EPILOG,
    )
    parser.add_argument(
        "--duration", default=None, metavar="TIME",
        help="chip time to record: 10min, 30s, 1.5h, 1d, 250ms (default: the scenario's duration)",
    )
    parser.add_argument(
        "--rate", type=bounded_option(limits.ODR_HZ), default=None, metavar="HZ", choices=(100, 200, 400, 1000, 2000),
        help="output data rate in Hz: 100, 200, 400, 1000 or 2000 (default: the chip's reset "
        "BW 0x00, 2000 Hz with the 523 Hz filter; note that generate defaults to 200 Hz)",
    )
    parser.add_argument(
        "--truth", type=Path, default=None, metavar="SCENARIO",
        help="true motion from a scenario file (TOML, docs/scenarios.md)",
    )
    parser.add_argument("-o", "--output", type=Path, required=True, metavar="FILE",
                        help="OUT.csv, OUT.npz or OUT.resd (Renode)")
    add_progress_options(parser)
    add_chip_options(parser, realtime=False)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.durations import parse_duration
    from bmg160_emu.io.atomic import held_signals
    from bmg160_emu.io.errors import FormatError
    from bmg160_emu.io.formats import format_for
    from bmg160_emu.session.record import BW_CODE_BY_ODR_HZ, RecordingInterrupted, record

    try:  # the registry's formats of a recording (io/recording.py)
        format_for("recording", args.output, writing=True, what="output")
    except FormatError as exc:
        raise CommandError(str(exc)) from None
    check_writable(args.output)
    if args.rate is not None and args.bandwidth is not None:
        raise CommandError("give --rate or --bandwidth, not both")
    if args.truth is not None and args.true_rate is not None:
        raise CommandError("give --truth or --true-rate, not both")
    scenario = None
    if args.truth is not None:
        from bmg160_emu.adcs.scenarios import ScenarioError, load_scenario

        try:
            scenario = load_scenario(args.truth)
        except ScenarioError as exc:  # its message starts with the file
            raise CommandError(str(exc)) from None
        except OSError as exc:
            raise CommandError(f"cannot read {args.truth}: {exc.strerror}") from None
    if args.duration is not None:
        try:
            duration = parse_duration(args.duration)
        except ValueError as exc:
            raise CommandError(f"--duration: {exc}") from None
    elif scenario is not None:
        duration = scenario.duration_s
    else:
        raise CommandError("--duration is needed (or a --truth scenario with its own duration)")
    if args.rate is not None:
        args.bandwidth = BW_CODE_BY_ODR_HZ[args.rate]
    chip = next(iter(chips_from_args(args).values()))
    samples = round(duration * chip.odr_hz)
    try:  # record holds every sample until it writes them: refuse what memory cannot hold
        limits.RECORD_SAMPLES.check(samples, f"--duration {args.duration}"
                                    if args.duration else f"{args.truth}: duration_s")
    except limits.LimitError as exc:
        raise CommandError(f"{exc} (at {chip.odr_hz:g} Hz; a lower --rate records longer)")\
            from None
    check_memory(samples * limits.RECORD_BYTES_PER_SAMPLE, f"recording {samples:,} samples "
                 f"({limits.RECORD_BYTES_PER_SAMPLE} bytes each until they are written)",
                 "record less (--duration) or at a lower --rate")
    if scenario is not None:
        chip.set_true_rate(scenario)

    reporter = progress_for(args, "record")
    stopped: KeyboardInterrupt | None = None
    try:
        with reporter.stage(samples, "samples") as update:
            rec = record(chip, duration, lambda done, total: update(done))
    except (ValueError, RuntimeError) as exc:
        raise CommandError(str(exc)) from None
    except RecordingInterrupted as exc:  # keep the samples so far: an honest shorter record
        stopped, rec = exc, exc.recording
    if scenario is not None:
        rec.metadata["truth"] = str(args.truth)
    if stopped is not None and len(rec) == 0:  # a file of no sample would look like a result
        stopped.kept = f"no sample recorded; {args.output} not written"  # type: ignore[attr-defined]
        raise stopped
    try:
        with held_signals():  # a signal now waits: the samples are written out first
            _write(args.output, rec)
    except KeyboardInterrupt as exc:  # the held signal, delivered once the file is whole
        if stopped is None:
            stopped = exc
    except OSError as exc:
        raise CommandError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    if stopped is not None:
        name = getattr(stopped, "signal_name", "SIGINT")
        whole = "interrupted" not in rec.metadata
        said = ("all of them (complete)" if whole
                else f"those {len(rec):,} (its settings say interrupted)")
        print(f"bmg160-emu record: interrupted by {name} after {len(rec):,} of "
              f"{rec.metadata.get('samples_planned', len(rec)):,} samples; {args.output} holds "
              f"{said}", file=sys.stderr)
        return 143 if name == "SIGTERM" else 130
    print(
        f"recorded {len(rec)} samples at {rec.odr_hz:g} Hz ({duration:g} s of chip time, "
        f"+-{rec.metadata['range_dps']} deg/s, {rec.lsb_per_dps:g} LSB/(deg/s)) to {args.output}"
    )
    return 0


def _write(path: Path, rec) -> None:
    """The recording as CSV, NPZ or RESD (Renode: channel 0 the output, 1 the truth), whole or
    not at all (io.recording)."""
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.io.errors import FormatError
    from bmg160_emu.io.recording import write_recording

    try:
        write_recording(rec, path)
    except FormatError as exc:
        raise CommandError(str(exc)) from None
