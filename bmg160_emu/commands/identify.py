"""``bmg160-emu identify``: N, B, T, K of each axis of a static record, with plots and a profile."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bmg160_emu.commands._common import add_command_parser

EPILOG = """\
examples:
  bmg160-emu identify noise.npy --rate 200
  bmg160-emu identify static.csv --plot adev.png --json
  bmg160-emu identify static.csv --profile-out my-gyro.toml --figures figs/ --compare

Inputs: CSV (one column per axis, optional time column t/t_s/time, '#' comments, the layout
of `bmg160-emu record` and `generate`), .npy (n or n x k array), .npz. The rate comes from
--rate or from the time column. The fit is a weighted least-squares fit of the closed-form
Allan variance (white + Gauss-Markov + random walk); the IEEE 952 read-offs are printed
beside it, labelled. PSDs are one-sided (white noise of density N reads 2 N^2).
--figures writes timeseries, histogram, adev and psd figures; with --compare, an emulator
record of the same length from the identified profile is overlaid (overlay_adev, overlay_psd,
overlay_time, one set per axis).
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = add_command_parser(
        subparsers,
        "identify",
        "identify N, B, T, K (Allan deviation + PSD + fit) from a static record",
        "Identify the noise parameters of each axis of a static gyroscope record "
        "and write a profile the generator loads back.",
        EPILOG,
    )
    parser.add_argument("file", type=Path, help="record: .csv, .npy or .npz (deg/s)")
    parser.add_argument(
        "--rate",
        type=float,
        default=None,
        metavar="HZ",
        help="sample rate in Hz (default: from the time column)",
    )
    parser.add_argument(
        "--columns",
        default=None,
        metavar="A,B,C",
        help="CSV columns holding the axes, by header name (default: x_dps,y_dps,z_dps or all)",
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
        help="with --figures: overlay an emulator record from the result",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
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
    parser.add_argument(
        "--method",
        choices=("allan", "gmwm"),
        default="allan",
        help="allan: weighted least squares of the Allan variance (default); gmwm: the "
        "generalized method of wavelet moments, efficient weights (docs/gmwm.md)",
    )
    parser.add_argument(
        "--bootstrap",
        type=int,
        default=0,
        metavar="N",
        help="with --method gmwm: also N parametric-bootstrap replicates per axis "
        "(percentile 95 %% intervals beside the asymptotic ones)",
    )
    parser.add_argument("--with-q", action="store_true", help="also fit quantization Q")
    parser.add_argument("--with-r", action="store_true", help="also fit rate ramp R")
    parser.add_argument(
        "--tau-min",
        type=float,
        default=None,
        metavar="S",
        help="shortest tau fitted (e.g. above the chip filter's time constant)",
    )
    parser.add_argument(
        "--tau-max", type=float, default=None, metavar="S", help="longest tau fitted"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.noise.identification import STAGES_PER_AXIS, IdentificationError, identify
    from bmg160_emu.noise.rate_record import RecordError, load_rate_record

    for path in (args.plot,):
        if path is not None and path.suffix.lower() not in (".png", ".svg"):
            raise CommandError(f"--plot must end in .png or .svg, not {path.name!r}")
    if args.compare and args.figures is None:
        raise CommandError("--compare needs --figures DIR")
    if args.bootstrap and args.method != "gmwm":
        raise CommandError("--bootstrap needs --method gmwm")
    if args.bootstrap < 0:
        raise CommandError(f"--bootstrap must be a number of replicates >= 0, not {args.bootstrap}")
    columns = [c.strip() for c in args.columns.split(",")] if args.columns else None
    try:
        record = load_rate_record(args.file, args.rate, columns)
        bar = _progress(record.rate_dps.shape[1] * STAGES_PER_AXIS)
        try:
            result = identify(
                record.rate_dps,
                record.rate_hz,
                axis_names=record.axis_names,
                with_q=args.with_q,
                with_r=args.with_r,
                tau_range=(args.tau_min, args.tau_max),
                source=str(args.file),
                progress=(lambda stage: _step(bar, stage)) if bar is not None else None,
            )
        finally:
            if bar is not None:
                bar.close()
        gmwm_fits = _apply_gmwm(args, record, result) if args.method == "gmwm" else None
    except (RecordError, IdentificationError) as exc:
        raise CommandError(str(exc)) from None

    written: list[Path] = []
    try:
        if args.profile_out is not None:
            from bmg160_emu.noise.profile import write_profile

            write_profile(
                result.to_profile(args.profile_out.stem),
                args.profile_out,
                header=f"identified by bmg160-emu identify from {args.file}\n"
                "units: N deg/s/sqrt(Hz), B deg/s, T s, K deg/s/sqrt(s), bias deg/s",
            )
            written.append(args.profile_out)
        if args.plot is not None:
            from bmg160_emu.noise import plots

            written.append(plots.save(plots.adev_figure(result.axes), args.plot))
        if args.figures is not None:
            written += _write_figures(args, record, result)
    except OSError as exc:
        raise CommandError(f"cannot write output: {exc}") from None

    if args.json:
        out = result.as_dict()
        for name, fit in (gmwm_fits or {}).items():
            out["axes"][name]["fit"] = fit.as_dict()
        out["written"] = [str(p) for p in written]
        json.dump(out, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        text = result.summary()
        if gmwm_fits:
            text = _gmwm_summary(text, gmwm_fits)
        print(text)
        for path in written:
            print(f"wrote {path}")
    return 0


def _apply_gmwm(args: argparse.Namespace, record, result) -> dict:
    """Replace each axis's Allan-fit N, B, T, K (Q, R) by GMWM's, intervals included; the
    Allan curve, PSD and read-offs stay (figures, JSON and profile then carry GMWM's values)."""
    import dataclasses

    import numpy as np

    from bmg160_emu.noise import gmwm
    from bmg160_emu.noise.identification import Estimate, IdentificationError
    from bmg160_emu.noise.wavelet import MIN_COEFFS_FRACTION, haar_wv

    model = ["WN", "GM", "RW"] + ["QN"] * args.with_q + ["DR"] * args.with_r
    fits = {}
    for i, axis in enumerate(result.axes):
        wv = haar_wv(record.rate_dps[:, i], record.rate_hz, MIN_COEFFS_FRACTION)
        keep = np.ones(wv.m.size, dtype=bool)
        if args.tau_min is not None:
            keep &= wv.taus_s >= args.tau_min
        if args.tau_max is not None:
            keep &= wv.taus_s <= args.tau_max
        wv = dataclasses.replace(
            wv, m=wv.m[keep], taus_s=wv.taus_s[keep], wv=wv.wv[keep], n_coeffs=wv.n_coeffs[keep]
        )
        try:
            fit = gmwm.gmwm_fit(wv, model)
            if args.bootstrap:
                fit = gmwm.bootstrap(fit, args.bootstrap, seed=args.seed)
        except gmwm.GMWMError as exc:
            raise IdentificationError(f"axis {axis.axis}: {exc}") from None
        est = {k: Estimate(e.value, e.ci_low, e.ci_high, e.unit) for k, e in fit.estimates.items()}
        notes = [  # the Allan fit's notes describe that fit: replaced
            f"{k} not resolved by this record (at the edge of its search range)"
            for k, at_edge in zip(fit.names, fit.at_bound)
            if at_edge
        ]
        if fit.p_value < 0.01:
            notes.append(
                f"the J test rejects the model (p = {fit.p_value:.2g}): try --with-q/--with-r"
            )
        result.axes[i] = dataclasses.replace(
            axis,
            N=est["N"],
            B=est["B"],
            T=est["T"],
            K=est["K"],
            Q=est.get("Q"),
            R=est.get("R"),
            fit_tau_range_s=(float(wv.taus_s[0]), float(wv.taus_s[-1])),
            fit_points=int(wv.m.size),
            chi2_reduced=fit.objective / max(fit.dof, 1),
            notes=notes,
        )
        fits[axis.axis] = fit
    return fits


def _gmwm_summary(text: str, fits: dict) -> str:
    lines = text.splitlines()
    for k, line in enumerate(lines):
        if line.startswith("fit:"):
            lines[k] = (
                "fit: GMWM, Haar wavelet variance with efficient two-step weights "
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


def _write_figures(args: argparse.Namespace, record, result) -> list[Path]:
    from bmg160_emu.commands._common import CommandError
    from bmg160_emu.noise import plots

    folder: Path = args.figures
    folder.mkdir(parents=True, exist_ok=True)
    ext = "." + args.format
    names = [a.axis for a in result.axes]
    figs = {
        "timeseries": plots.time_series_figure(record.rate_dps, record.rate_hz, names),
        "histogram": plots.histogram_figure(record.rate_dps, names),
        "adev": plots.adev_figure(result.axes),
        "psd": plots.psd_figure(result.axes, record.rate_hz),
    }
    if args.compare:
        from bmg160_emu.noise import NoiseGenerator
        from bmg160_emu.noise.discretization import SUPPORTED_RATES_HZ
        from bmg160_emu.noise.identification import identify_axis

        chip_rate = min(SUPPORTED_RATES_HZ, key=lambda r: abs(r / record.rate_hz - 1))
        if abs(chip_rate / record.rate_hz - 1) > 0.01:
            raise CommandError(
                f"--compare: the record's rate {record.rate_hz:g} Hz is not a BMG160 output "
                "data rate (100, 200, 400, 1000, 2000 Hz)"
            )
        gen = NoiseGenerator(result.to_profile(), rate_hz=chip_rate, seed=args.seed)
        emulated = gen.generate(record.rate_dps.shape[0])
        for i, axis in enumerate(result.axes):
            emu = identify_axis(emulated[:, i], record.rate_hz, axis.axis)
            overlays = plots.overlay_figures(
                record.rate_dps[:, i], emulated[:, i], record.rate_hz, axis, emu
            )
            for key, fig in overlays.items():
                figs[f"{key}_{axis.axis}"] = fig
    return [plots.save(fig, folder / f"{key}{ext}") for key, fig in figs.items()]
