"""``bmg160-emu compare``: whether a noise profile's emulated records are indistinguishable
from a recording, figure by figure against stated thresholds (noise/verdict.py)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bmg160_emu import limits
from bmg160_emu.commands._common import Subparsers, add_command_parser, bounded_option

EPILOG = """\
examples:
  bmg160-emu identify static.csv --profile-out mine.toml
  bmg160-emu compare static.csv mine.toml
  bmg160-emu compare static.csv mine.toml --seeds 40 --figure verdict.png --json

The profile is drawn SEEDS times at the recording's length and rate, as generate writes it
(its output stage included), and per axis the recording is set against the spread of those
records: std ratio (within 3 %), autocorrelation at lags 1-10 (lags 1-5 within 0.05), PSD
bins inside the recording's 95 % band (>= 90 %), Allan deviation at octave taus 0.2 s ..
L/10: the emulated median inside the recording's 95 % Greenhall band (>= 97 % of taus) and
the recording inside the emulated 2.5-97.5 % range (>= 95 %). --figure draws the recording
over the emulated band. Exit status 0 when every figure passes, 1 when one fails, 2 on bad
input. Record columns are the profile's axes in order.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers, "compare",
        "is a profile's emulated noise indistinguishable from a recording? (pass/fail)",
        "Draw a noise profile many times at a recording's length and rate and set the "
        "recording against the spread: std, autocorrelation, PSD and Allan deviation, each "
        "against a stated threshold.",
        EPILOG,
    )
    parser.add_argument("recording", type=Path, metavar="RECORDING",
                        help="static record: .csv, .npy, .npz, .resd (deg/s)")
    parser.add_argument("profile", metavar="PROFILE",
                        help="noise profile: a built-in name or a TOML/YAML/.m file")
    parser.add_argument("--rate", type=bounded_option(limits.SAMPLE_RATE_HZ), default=None,
                        metavar="HZ", help="the recording's sample rate (default: its time "
                        "column)")
    parser.add_argument("--columns", default=None, metavar="A,B,C",
                        help="CSV columns holding the axes, by header name")
    parser.add_argument("--record-units", choices=("deg/s", "rad/s"), default=None,
                        help="unit of a recording that states none (as identify's)")
    parser.add_argument("--seeds", type=bounded_option(limits.RUNS), default=20, metavar="N",
                        help="emulated records (default 20)")
    parser.add_argument("--figure", type=Path, default=None, metavar="FILE.png",
                        help="draw the recording over the emulated band (.png or .svg)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError, check_writable
    from bmg160_emu.io.rates import RateFileError, load_rate_record
    from bmg160_emu.noise.discretization import SUPPORTED_RATES_HZ
    from bmg160_emu.noise.profile import ProfileError, load_profile
    from bmg160_emu.noise.verdict import compare_profile, verdict_dict

    if args.figure is not None:
        if args.figure.suffix.lower() not in (".png", ".svg"):
            raise CommandError(f"--figure must end in .png or .svg, not {args.figure.name!r}")
        check_writable(args.figure)
    try:
        profile = load_profile(args.profile)
    except ProfileError as exc:
        raise CommandError(str(exc)) from None
    columns = [c.strip() for c in args.columns.split(",")] if args.columns else None
    try:
        record = load_rate_record(args.recording, args.rate, columns, args.record_units)
    except RateFileError as exc:
        text = str(exc)
        raise CommandError(text if text.startswith(str(args.recording))
                           else f"{args.recording}: {text}") from None
    rate = float(record.rate_hz)
    own = profile.output.rate_hz if profile.output is not None else None
    if rate not in SUPPORTED_RATES_HZ and not (own and abs(rate - own) <= 1e-6 * own):
        raise CommandError(f"{args.recording}: its rate {rate:g} Hz is not an output data rate "
                           "the generator draws (100, 200, 400, 1000, 2000 Hz), nor the rate "
                           f"{args.profile} was identified at"
                           + (f" ({own:g} Hz)" if own else ""))
    if own and abs(rate - own) <= 1e-6 * own:
        rate = float(own)  # the profile's own rate, as written (the record's to 1e-6)
    bar = _progress(args.seeds)
    try:
        verdict = compare_profile(record.rate_dps, rate, profile, args.seeds,
                                  tuple(record.axis_names) if record.axis_names else ("x", "y", "z"),
                                  progress=(lambda done: bar.update(1)) if bar else None)
    finally:
        if bar is not None:
            bar.close()
    if args.figure is not None:
        from bmg160_emu.io.atomic import atomic_path
        from bmg160_emu.noise import plots
        from bmg160_emu.noise.verdict import verdict_figure

        try:
            with atomic_path(args.figure) as partial:
                plots.save(verdict_figure(verdict), partial)
        except OSError as exc:
            raise CommandError(f"cannot write {args.figure}: {exc.strerror or exc}") from None
    if args.json:
        json.dump(verdict_dict(verdict), sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(f"recording: {args.recording}; profile: {profile.name}")
        print(verdict.text())
        if args.figure is not None:
            print(f"wrote {args.figure}")
    return 0 if verdict.passed else 1


def _progress(steps: int):
    from bmg160_emu.commands._extras import available

    if not sys.stderr.isatty() or not available("tqdm"):
        return None
    from tqdm import tqdm

    return tqdm(total=steps, unit="record", desc="compare", file=sys.stderr)
