"""``bmg160-emu identify``: N, K and Gauss-Markov terms of each axis of a static record (or of
an Allan deviation curve), with plots, a profile and exports for Kalibr and MATLAB."""

from __future__ import annotations

import argparse
import json
import sys
from functools import partial
from pathlib import Path
from typing import Any

from bmg160_emu import limits
from bmg160_emu.commands._common import (
    Subparsers,
    add_command_parser,
    add_progress_options,
    bounded_option,
    progress_for,
)

EPILOG = """\
examples:
  bmg160-emu identify noise.npy --rate 200
  bmg160-emu identify static.csv --plot adev.png --json
  bmg160-emu identify static.csv --profile-out my-gyro.toml --figures figs/ --compare
  bmg160-emu identify static.csv --skip 40min --units rad/s --kalibr-out imu.yaml
  bmg160-emu identify adev.csv --curve --rate 100 --duration 2.8h --profile-out mine.toml

Inputs: CSV (one column per axis, optional time column t/t_s/time, '#' comments, the layout
of `bmg160-emu record` and `generate`, the EuRoC/TUM-VI data.csv; rad/s columns converted), .npy (n or n x k array), .npz, .resd (Renode, channel
0), the firmware's UART stream (.txt from `firmware capture` or a board's serial port, whose
ODR --rate gives); with --curve, an Allan deviation CSV (tau, then adev [low high] per
axis; allan_variance_ros's 7 columns, non-overlapping, in deg/s) and the record's --samples
or --duration. The rate comes from --rate or from the time column.

The fit (docs/identification.md): weighted least squares of the closed-form Allan variance
of white noise through the sensor's output filter + Gauss-Markov terms (B_i, T_i) + random
walk + sinusoidal lines; the number of terms is chosen by AICc (or --poles). The sensor's
output stage is found on the record (its filter on the PSD, the LSB its values sit on, PSD
lines) and written into --profile-out, so that generate reproduces the record (--no-output-
stage: as before, the fit starts where the white slope does). Warm-up and bias steps are
reported. The IEEE 952 read-offs are printed beside the fit, labelled. PSDs are one-sided
(white noise of density N reads 2 N^2). --figures writes timeseries, histogram, adev and psd
figures; with --compare, an emulator record of the same length is overlaid.
"""


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "identify",
        "identify N, B, T, K (Allan deviation + PSD + fit) from a static record",
        "Identify the noise parameters of each axis of a static gyroscope record "
        "and write a profile the generator loads back.",
        EPILOG,
    )
    parser.add_argument("file", type=Path, metavar="FILE", help="record: .csv, .npy, .npz, .resd (deg/s) or "
                        "the firmware's UART stream (.txt)")
    parser.add_argument(
        "--rate",
        type=bounded_option(limits.SAMPLE_RATE_HZ),
        default=None,
        metavar="HZ",
        help="sample rate in Hz (default: from the time column)",
    )
    parser.add_argument(
        "--columns",
        default=None,
        metavar="A,B,C",
        help="CSV columns holding the axes, by header name (default: x_dps,y_dps,z_dps, x,y,z, "
        "gx,gy,gz, else those whose names carry a rate unit, else all)",
    )
    parser.add_argument(
        "--record-units", choices=("deg/s", "rad/s"), default=None,
        help="unit of a record that states none (ROS and PX4 log rad/s); a CSV column named "
        "with its unit (w_x [rad s^-1], gx_rad_s, x_dps) is converted by itself",
    )
    parser.add_argument("--json", action="store_true", help="print a JSON result instead")
    parser.add_argument(
        "--plot",
        type=Path,
        default=None,
        metavar="ADEV.png",
        help="write the Allan deviation figure (.png or .svg)",
    )
    parser.add_argument(
        "--figures", type=Path, default=None, metavar="DIR", help="write every figure into DIR"
    )
    parser.add_argument(
        "--format",
        choices=("png", "svg"),
        default="png",
        help="figure format for --figures (default png)",
    )
    parser.add_argument(
        "--compare",
        action="store_true",
        help="with --figures: the recording over the band of emulated records from the result "
        "(median and 2.5-97.5 %%, --verdict-seeds of them) and the verdict",
    )
    parser.add_argument(
        "--verdict-seeds", type=bounded_option(limits.RUNS), default=20, metavar="N",
        help="emulated records of the verdict (bmg160-emu compare) printed after "
        "--profile-out and drawn by --compare (default 20, fewer when they would take over "
        "a minute)",
    )
    parser.add_argument(
        "--no-verdict", action="store_true",
        help="do not print the verdict after --profile-out",
    )
    parser.add_argument(
        "--seed",
        type=bounded_option(limits.SEED),
        default=None,
        metavar="N",
        help="seed of the --compare emulator record (default: random; the same seed as the "
        "recording's own generator would reproduce its noise almost sample for sample)",
    )
    parser.add_argument(
        "--profile-out",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="write the identified profile (loadable by generate)",
    )
    parser.add_argument("--with-q", action="store_true", help="also fit quantization Q")
    parser.add_argument("--with-r", action="store_true", help="also fit rate ramp R")
    parser.add_argument(
        "--tau-min",
        type=bounded_option(limits.TAU_S),
        default=None,
        metavar="S",
        help="shortest tau fitted (e.g. above the chip filter's time constant)",
    )
    parser.add_argument(
        "--tau-max", type=bounded_option(limits.TAU_S), default=None, metavar="S", help="longest tau fitted"
    )
    parser.add_argument(
        "--poles",
        default="auto",
        metavar="N|auto",
        help="number of Gauss-Markov terms (default auto: chosen by AICc; 1 for the firmware)",
    )
    parser.add_argument(
        "--flicker", action="store_true", help="also fit a 1/f bias (a fixed bank of poles)"
    )
    parser.add_argument(
        "--method",
        default="wls",
        help="wls (or allan): weighted least squares of the Allan variance (default); gmwm: "
        "the generalized method of wavelet moments, efficient weights (docs/gmwm.md)",
    )
    parser.add_argument(
        "--bootstrap",
        type=bounded_option(limits.BOOTSTRAP),
        default=0,
        metavar="N",
        help="with --method gmwm: also N parametric-bootstrap replicates per axis "
        "(percentile 95 %% intervals beside the asymptotic ones)",
    )
    parser.add_argument(
        "--skip", default=None, metavar="TIME", help="drop the start (warm-up), e.g. 40min"
    )
    parser.add_argument(
        "--units",
        choices=("deg/s", "rad/s"),
        default="deg/s",
        help="units of the summary, --json, --adev-out (the profile stays in deg/s)",
    )
    parser.add_argument(
        "--adev-out", type=Path, default=None, metavar="FILE.csv",
        help="write each axis's Allan deviation with its interval",
    )
    parser.add_argument(
        "--kalibr-out", type=Path, default=None, metavar="imu.yaml",
        help="write Kalibr's gyroscope noise fields (rad/s units)",
    )
    parser.add_argument(
        "--matlab-out", type=Path, default=None, metavar="FILE.m",
        help="write a MATLAB gyroparams(...) block (rad/s units)",
    )
    parser.add_argument(
        "--curve", action="store_true",
        help="the file is an Allan deviation curve (CSV), not samples",
    )
    parser.add_argument(
        "--samples", type=bounded_option(limits.CURVE_SAMPLES), default=None, metavar="N",
        help="with --curve: number of samples of the record behind the curve",
    )
    parser.add_argument(
        "--duration", default=None, metavar="TIME",
        help="with --curve: length of the record behind the curve (with --rate)",
    )
    parser.add_argument(
        "--curve-units", choices=("deg/s", "rad/s", "deg/h"), default="deg/s",
        help="with --curve: units of the curve (allan_variance_ros writes deg/s: it converts "
        "the gyroscope's rad/s before averaging)",
    )
    parser.add_argument(
        "--curve-kind", choices=("auto", "overlapping", "non-overlapping"), default="auto",
        help="with --curve: the estimator behind the curve (auto: as the file says; "
        "allan_variance_ros's is non-overlapping; else overlapping)",
    )
    parser.add_argument(
        "--no-output-stage", action="store_true",
        help="do not fit the sensor's output filter, quantization and lines (the fit then "
        "starts where the white -1/2 slope does)",
    )
    add_progress_options(parser)
    parser.set_defaults(func=run)


def _options(args: argparse.Namespace) -> dict:
    """The fit options from the command line, or a CommandError naming the bad one."""
    from bmg160_emu.commands._common import CommandError, check_writable
    from bmg160_emu.durations import parse_duration

    for out in (args.profile_out, args.adev_out, args.kalibr_out, args.matlab_out, args.plot):
        if out is not None:  # refused by its own name before the fit, not as a hidden .part
            check_writable(out)
    if args.poles == "auto":
        poles = None
    else:
        try:
            poles = int(args.poles)
        except ValueError:
            raise CommandError(f"--poles must be a number of terms or 'auto', not {args.poles!r}")
        if not 0 <= poles <= 5:
            raise CommandError(f"--poles must be 0 to 5 (or auto), not {poles}")
    skip = 0.0
    if args.skip is not None:
        try:
            skip = parse_duration(args.skip, allow_zero=True)
        except ValueError as exc:
            raise CommandError(f"--skip: {exc}") from None
    for name in ("tau_min", "tau_max"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise CommandError(f"--{name.replace('_', '-')} must be a positive tau in s")
    # GMWM works on the samples after the Allan fit (curve, PSD, read-offs) has run
    method = "wls" if args.method in ("allan", "gmwm") else args.method
    return {"poles": poles, "flicker": args.flicker, "method": method, "skip_s": skip,
            "with_q": args.with_q, "with_r": args.with_r,
            "tau_range": (args.tau_min, args.tau_max),
            "output_stage": not args.no_output_stage}


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.io.atomic import OutputError, write_together
    from bmg160_emu.io.rate_table import RateFileError
    from bmg160_emu.noise.identify import IdentificationError
    from bmg160_emu.noise.interop import InteropError

    for path in (args.plot,):
        if path is not None and path.suffix.lower() not in (".png", ".svg"):
            raise CommandError(f"--plot must end in .png or .svg, not {path.name!r}")
    if args.compare and args.figures is None:
        raise CommandError("--compare needs --figures DIR")
    if args.curve and (args.figures is not None):
        raise CommandError("--figures needs samples: not available with --curve")
    if args.bootstrap and args.method != "gmwm":
        raise CommandError("--bootstrap needs --method gmwm")
    if args.bootstrap < 0:
        raise CommandError(f"--bootstrap must be a number of replicates >= 0, not {args.bootstrap}")
    if args.method == "gmwm" and args.curve:
        raise CommandError("--method gmwm needs the samples: not available with --curve")
    options = _options(args)
    gmwm_fits = None
    try:
        if args.curve:
            record, result = None, _identify_curve(args, options)
        else:
            record, result = _identify_record(args, options)
            if args.method == "gmwm":
                from bmg160_emu.noise.gmwm_identification import gmwm_identification

                boot = progress_for(args, "identify").start(  # ends itself when done
                    args.bootstrap * record.rate_dps.shape[1], "bootstrap fits")
                result, gmwm_fits = gmwm_identification(
                    result, record.rate_dps, with_q=args.with_q, with_r=args.with_r,
                    tau_min_s=args.tau_min, tau_max_s=args.tau_max, bootstrap=args.bootstrap,
                    seed=args.seed, progress=boot.update)
    except (RateFileError, IdentificationError, InteropError) as exc:
        text = str(exc)  # "record too short" and the like: name the file once
        raise CommandError(text if text.startswith(str(args.file)) else f"{args.file}: {text}") \
            from None

    verdict = None
    if record is not None and (args.compare or (args.profile_out is not None
                                                and not args.no_verdict)):
        verdict = _verdict(args, record, result)
    jobs = _output_jobs(args, result)
    if args.figures is not None:
        jobs += _figure_jobs(args, record, result)
        if verdict is not None and args.compare:
            jobs += _verdict_figure_jobs(args, verdict)
    try:  # all together, or none (issue 35)
        written = write_together(jobs, args.figures)
    except OutputError as exc:
        raise CommandError(str(exc)) from None
    if args.json:
        out = result.as_dict(args.units)
        if verdict is not None:
            from bmg160_emu.noise.verdict import verdict_dict

            out["verdict"] = verdict_dict(verdict)
        for name, fit in (gmwm_fits or {}).items():
            out["axes"][name]["fit"] = fit.as_dict()  # the fit that gave the values
        out["written"] = [str(p) for p in written]
        json.dump(out, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        text = result.summary(args.units)
        print(_gmwm_summary(text, gmwm_fits) if gmwm_fits else text)
        stage = _output_stage_line(result)
        if stage:
            print(stage)
        if verdict is not None:
            print(verdict.text())
        for path in written:
            print(f"wrote {path}")
    for axis in result.axes:  # a curve in the wrong units: said where it cannot be missed
        for note in axis.notes:
            if note.startswith("implausible"):
                print(f"bmg160-emu identify: warning: axis {axis.axis}: {note}", file=sys.stderr)
    return 0


READING_NOTE_BYTES = 20_000_000  # files from this size get a line before and after reading
# The verdict after --profile-out emulates at most this many samples per axis in all (its
# records times the record's length): about 30 s on two cores at load 1 (1.5 us a sample for
# three axes at load 7, tools: compare_profile timed on a 1e6-sample record). A count of
# samples, not a timing, so the same record gives the same verdict on every host.
VERDICT_SAMPLES = 20_000_000
VERDICT_MIN_SEEDS = 5  # fewer emulated records say too little: the verdict is left out


def _verdict(args: argparse.Namespace, record, result):
    """The verdict of the identified profile against the record (noise.verdict), with as
    many of --verdict-seeds as VERDICT_SAMPLES allows, or None with a line saying why and
    how to get it."""
    from bmg160_emu.noise.discretization import SUPPORTED_RATES_HZ
    from bmg160_emu.noise.verdict import compare_profile

    how = f"bmg160-emu compare {args.file} {args.profile_out or 'PROFILE'}"
    profile = result.to_profile(args.profile_out.stem if args.profile_out else "identified")
    own = getattr(profile.output, "rate_hz", None)  # a profile runs at its record's own rate
    if float(record.rate_hz) not in SUPPORTED_RATES_HZ and own != float(record.rate_hz):
        print(f"bmg160-emu identify: no verdict: the record's rate {record.rate_hz:g} Hz is not "
              "an output data rate the generator draws (100, 200, 400, 1000, 2000 Hz)",
              file=sys.stderr)
        return None
    samples = int(record.rate_dps.shape[0])
    seeds = min(args.verdict_seeds, VERDICT_SAMPLES // max(samples, 1))
    if seeds < VERDICT_MIN_SEEDS and not args.compare:
        print(f"bmg160-emu identify: no verdict: {VERDICT_MIN_SEEDS} emulated records of "
              f"{samples:,} samples are more than the {VERDICT_SAMPLES:,} samples identify "
              f"spends on it; run `{how} --seeds N`", file=sys.stderr)
        return None
    seeds = max(seeds, VERDICT_MIN_SEEDS)
    names = tuple(a.axis for a in result.axes)
    print(f"bmg160-emu identify: verdict over {seeds} emulated records "
          f"(`{how}` gives more) ...", file=sys.stderr, flush=True)
    return compare_profile(record.rate_dps, record.rate_hz, profile, seeds, names)


def _verdict_figure_jobs(args: argparse.Namespace, verdict) -> list[tuple[Path, Any]]:
    from bmg160_emu.noise.verdict import verdict_figure

    return [(args.figures / f"compare.{args.format}",
             partial(_save_figure, verdict_figure(verdict)))]


def _output_stage_line(result) -> str:
    """The output stage the profile carries, with the BW code of the chip family that has
    the same filter at the record's rate (register spec 5.3), if one does."""
    from bmg160_emu.noise.bandwidths import BANDWIDTHS, LOWPASS_ORDER

    stage = result.output_stage()
    if stage is None:
        return ""
    parts = []
    if stage.corner_hz is not None:
        text = f"order {stage.order} Butterworth at {stage.corner_hz:.4g} Hz"
        for code, (odr, bandwidth) in BANDWIDTHS.items():
            if (odr == result.rate_hz and stage.order == LOWPASS_ORDER
                    and abs(stage.corner_hz / bandwidth - 1) < 0.05):
                text += (f" (the chip family's BW code {code}: {bandwidth:g} Hz at {odr} Hz "
                         "ODR)")
        parts.append(text)
    if stage.lsb_dps:
        parts.append(f"LSB {stage.lsb_dps:.6g} deg/s")
    return ("sensor output stage (--profile-out writes it, generate applies it): "
            + ", ".join(parts))


def _identify_record(args: argparse.Namespace, options: dict):
    from bmg160_emu.io.rates import load_rate_record
    from bmg160_emu.noise.identify import STAGES_PER_AXIS, identify

    columns = [c.strip() for c in args.columns.split(",")] if args.columns else None
    import time

    size = args.file.stat().st_size if args.file.is_file() else 0
    started = time.perf_counter()
    if size >= READING_NOTE_BYTES:  # a large text file takes 10-20 s: say so, then how long
        print(f"bmg160-emu identify: reading {args.file} ({size / 1e6:.0f} MB) ...",
              file=sys.stderr, flush=True)
    record = load_rate_record(args.file, args.rate, columns, args.record_units)
    if size >= READING_NOTE_BYTES:
        print(f"bmg160-emu identify: read {record.rate_dps.shape[0]:,} samples x "
              f"{record.rate_dps.shape[1]} axes in {time.perf_counter() - started:.1f} s",
              file=sys.stderr, flush=True)
    if record.unit != "deg/s":  # said, since every figure below is in deg/s
        print(f"bmg160-emu identify: {args.file}: rates in {record.unit}, read as deg/s",
              file=sys.stderr)
    from bmg160_emu.io.partial import partial_note

    cut = partial_note(args.file)
    if cut:  # read all the same: what it holds is true, but shorter than was asked for
        print(f"bmg160-emu identify: warning: {args.file} is partial ({cut})", file=sys.stderr)
    bar = _progress(record.rate_dps.shape[1] * STAGES_PER_AXIS)
    try:
        result = identify(
            record.rate_dps,
            record.rate_hz,
            axis_names=record.axis_names,
            source=str(args.file),
            progress=(lambda stage: _step(bar, stage)) if bar is not None else None,
            **options,
        )
    finally:
        if bar is not None:
            bar.close()
    return record, result


def _identify_curve(args: argparse.Namespace, options: dict):
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.durations import parse_duration
    from bmg160_emu.noise.identification_result import Identification
    from bmg160_emu.noise.identify import identify_curve
    from bmg160_emu.noise.interop import read_adev_csv

    if args.rate is None:
        raise CommandError("--curve needs --rate HZ (the record's sample rate)")
    if (args.samples is None) == (args.duration is None):
        raise CommandError("--curve needs the record's length: --samples N or --duration TIME")
    if args.skip is not None:
        raise CommandError("--skip applies to samples, not to an Allan deviation curve")
    try:
        n = args.samples if args.samples is not None else round(
            parse_duration(args.duration) * args.rate)
    except ValueError as exc:
        raise CommandError(f"--duration: {exc}") from None
    if n < 2:
        raise CommandError(f"--samples must be at least 2, not {n}")
    taus, axes = read_adev_csv(args.file, args.curve_units)
    if taus[-1] * args.rate > n / 2:
        raise CommandError(
            f"{args.file}: the curve reaches tau = {taus[-1]:g} s, more than half the record "
            f"({n} samples at {args.rate:g} Hz): check --samples/--duration and --rate"
        )
    options = {k: v for k, v in options.items() if k not in ("skip_s", "output_stage")}
    results = []
    for a in axes:
        kind = args.curve_kind if args.curve_kind != "auto" else (a["kind"] or "overlapping")
        results.append(identify_curve(taus, a["adev"], args.rate, n, axis=a["name"], ci=a["ci"],
                                      overlapping=kind == "overlapping", **options))
    return Identification(float(args.rate), n, results, str(args.file))


def _output_jobs(args: argparse.Namespace, result) -> list[tuple[Path, Any]]:
    """(target, write(temporary path)) of every output file option given."""
    from bmg160_emu.noise import interop

    jobs: list[tuple[Path, Any]] = []
    if args.profile_out is not None:
        from bmg160_emu.noise.profile_writer import write_profile

        jobs.append((args.profile_out, lambda temp: write_profile(
            result.to_profile(args.profile_out.stem), temp,
            header=f"identified by bmg160-emu identify from {args.file}\n"
            "units: N deg/s/sqrt(Hz), B deg/s, T s, K deg/s/sqrt(s), bias deg/s")))
    if args.adev_out is not None:
        jobs.append((args.adev_out, lambda temp: interop.write_adev_csv(temp, result,
                                                                        args.units)))
    if args.kalibr_out is not None:
        jobs.append((args.kalibr_out, lambda temp: temp.write_text(
            interop.kalibr_yaml(result, result.rate_hz), encoding="utf-8")))
    if args.matlab_out is not None:
        jobs.append((args.matlab_out, lambda temp: temp.write_text(
            interop.matlab_gyroparams(result), encoding="utf-8")))
    if args.plot is not None:
        from bmg160_emu.noise import plots

        jobs.append((args.plot, lambda temp: plots.save(plots.adev_figure(result.axes), temp)))
    return jobs


def _save_figure(fig: Any, temp: Path) -> None:
    from bmg160_emu.noise import plots

    plots.save(fig, temp)


def _gmwm_summary(text: str, fits: dict) -> str:
    lines = text.splitlines()
    for k, line in enumerate(lines):
        if line.startswith("fit:"):
            lines[k] = (
                "fit: GMWM, Haar wavelet variance with iterated efficient weights "
                "(white + Gauss-Markov + random walk); 95 % asymptotic intervals"
            )
            break
    lines.append("")
    for name, fit in fits.items():
        lines.append(
            f"axis {name} GMWM: model {'+'.join(fit.model)}, J = {fit.objective:.2f} on "
            f"{fit.dof} dof (p = {fit.p_value:.3f}), WIC {fit.wic:.2f}"
        )
        for key, e in fit.estimates.items():
            if e.boot_low is not None:
                lines.append(f"  {key} bootstrap 95 %: [{e.boot_low:.3g}, {e.boot_high:.3g}]")
    return "\n".join(lines)


def _progress(steps: int):
    if not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    return tqdm(total=steps, unit="step", desc="identify", file=sys.stderr)


def _step(bar, stage: str) -> None:
    bar.set_postfix_str(stage, refresh=False)
    bar.update(1)


def _figure_jobs(args: argparse.Namespace, record, result) -> list[tuple[Path, Any]]:
    """(target, write(temporary path)) of every figure of --figures."""
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.noise import plots

    folder: Path = args.figures
    ext = "." + args.format
    names = [a.axis for a in result.axes]
    figs = {
        "timeseries": plots.time_series_figure(record.rate_dps, record.rate_hz, names),
        "histogram": plots.histogram_figure(record.rate_dps, names),
        "adev": plots.adev_figure(result.axes),
        "psd": plots.psd_figure(result.axes, record.rate_hz),
    }
    if args.compare:
        from bmg160_emu.noise.discretization import SUPPORTED_RATES_HZ
        from bmg160_emu.noise.sensor_noise import profile_noise

        chip_rate = min(SUPPORTED_RATES_HZ, key=lambda r: abs(r / record.rate_hz - 1))
        if getattr(result.output_stage(), "rate_hz", None) == float(record.rate_hz):
            chip_rate = float(record.rate_hz)  # the profile runs at its record's own rate
        if abs(chip_rate / record.rate_hz - 1) > 0.01:
            raise CommandError(f"--compare: the record's rate {record.rate_hz:g} Hz is not a "
                               "BMG160 output data rate (100, 200, 400, 1000, 2000 Hz)")
        # what generate writes from the profile: its output stage included; one record for
        # the look of the time series (its ADEV and PSD are drawn as the band of many
        # records: compare.png, _write_verdict_figure; one record's ADEV at L/10 scatters by
        # a factor 2-4 from seed to seed, issue 35)
        gen = profile_noise(result.to_profile(), chip_rate, seed=args.seed)
        emulated = gen.generate(record.rate_dps.shape[0])
        for i, axis in enumerate(result.axes):
            figs[f"overlay_time_{axis.axis}"] = plots.overlay_time_figure(
                record.rate_dps[:, i], emulated[:, i], record.rate_hz, axis.axis)
    return [(folder / f"{key}{ext}", partial(_save_figure, fig)) for key, fig in figs.items()]
