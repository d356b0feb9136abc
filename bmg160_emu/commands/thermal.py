"""``bmg160-emu thermal``: each axis's bias as a polynomial of temperature, from a thermal log."""

from __future__ import annotations

import argparse
import json
import math
from functools import partial
from pathlib import Path
from typing import Any

from bmg160_emu import limits
from bmg160_emu.commands._common import Subparsers, add_command_parser, bounded_option

EPILOG = """\
examples:
  bmg160-emu thermal chamber.csv --px4-params tc_gyro.params
  bmg160-emu thermal orbit-log.csv --temperature-column temp_c --order 2 --errors-out unit.toml
  bmg160-emu thermal log.csv --noise-profile my-gyro.toml --reference 25 --json

Input: a CSV of a unit at rest through a temperature change (a thermal chamber ramp, an
orbit's cycles): a time column (t, t_s, time, time_s), the rate of each axis in deg/s
(x_dps, y_dps, z_dps or x, y, z) and the die temperature in deg C (temp_c, temperature_c,
temp or --temperature-column). The fit is generalised least squares on block means with the
covariance the gyro's noise model implies (--noise-profile, or identified from the residuals),
so its intervals hold at their level (docs/error-budget.md). Outputs: the coefficients with
95 % intervals, PX4's TC_G* parameters (rad/s, a QGroundControl .params file) and the
[errors] table of a noise profile (zero_rate_offset_dps, bias_tc_dps_per_k).
"""

TEMPERATURE_COLUMNS = ("temp_c", "temperature_c", "temp", "temperature", "t_die_c")
AXIS_COLUMNS = (("x_dps", "y_dps", "z_dps"), ("x", "y", "z"), ("gx", "gy", "gz"))


def register(subparsers: Subparsers) -> None:
    parser = add_command_parser(
        subparsers,
        "thermal",
        "fit each axis's bias as a polynomial of temperature (PX4 TC_G*, profile errors)",
        "Fit the bias of each axis as a polynomial of the die temperature from a record of a "
        "unit at rest through a temperature change, with intervals that allow for the gyro's "
        "correlated noise.",
        EPILOG,
    )
    parser.add_argument("file", type=Path, metavar="FILE", help="CSV with time, x, y, z (deg/s) and temperature")
    parser.add_argument("--temperature-column", default=None, metavar="NAME",
                        help=f"the temperature column (default: one of {', '.join(TEMPERATURE_COLUMNS)})")
    parser.add_argument("--order", type=bounded_option(limits.POLYNOMIAL_ORDER), default=3, choices=(0, 1, 2, 3),
                        help="polynomial order (default 3, as PX4)")
    parser.add_argument("--reference", type=bounded_option(limits.REFERENCE_TEMPERATURE_C), default=None, metavar="DEGC",
                        help="reference temperature of the polynomial (default: mid-range)")
    parser.add_argument("--block", default="60s", metavar="TIME",
                        help="block length the fit averages over (default 60s)")
    parser.add_argument("--noise-profile", default=None, metavar="NAME|FILE",
                        help="the unit's noise profile (default: identified from the residuals)")
    parser.add_argument("--px4-params", type=Path, default=None, metavar="FILE",
                        help="write PX4's TC_G0_* parameters as a QGroundControl .params file")
    parser.add_argument("--px4-instance", type=bounded_option(limits.PX4_INSTANCE), default=0, metavar="N",
                        help="the gyro instance N of TC_G<N>_* (default 0)")
    parser.add_argument("--errors-out", type=Path, default=None, metavar="FILE.toml",
                        help="write the [errors] table of a noise profile")
    parser.add_argument("--json", action="store_true", help="print the fit as JSON")
    parser.set_defaults(func=run)


def _choose(temperature_column: str | None):
    def choose(header: list[str] | None, width: int, where: str) -> tuple[int, list[int]]:
        from bmg160_emu.commands._common import CommandError

        if header is None:
            raise CommandError(f"{where}: a thermal log needs a header row naming its columns")
        names = [h.lower() for h in header]
        time = next((names.index(n) for n in ("t_s", "t", "time_s", "time") if n in names), None)
        if time is None:
            raise CommandError(f"{where}: no time column (t, t_s, time, time_s)")
        axes = next((cols for cols in AXIS_COLUMNS if all(c in names for c in cols)), None)
        if axes is None:
            raise CommandError(f"{where}: no rate columns (x_dps, y_dps, z_dps or x, y, z)")
        wanted = [temperature_column.lower()] if temperature_column else list(TEMPERATURE_COLUMNS)
        temp = next((names.index(n) for n in wanted if n in names), None)
        if temp is None:
            raise CommandError(f"{where}: no temperature column ({', '.join(wanted)}; "
                               "--temperature-column names another)")
        return time, [names.index(c) for c in axes] + [temp]

    return choose


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from bmg160_emu.commands._common import CommandError, check_writable
    from bmg160_emu.durations import parse_duration
    from bmg160_emu.io.atomic import OutputError, write_together
    from bmg160_emu.io.csv_table import read_csv_table
    from bmg160_emu.io.rate_table import RateFileError
    from bmg160_emu.io.time_column import check_time_column
    from bmg160_emu.noise.identify import IdentificationError
    from bmg160_emu.noise.thermal_fit import ThermalFitError, fit_bias_temperature

    for out in (args.px4_params, args.errors_out):
        if out is not None:
            check_writable(out)
    try:
        block_s = parse_duration(args.block)
    except ValueError as exc:
        raise CommandError(f"--block: {exc}") from None
    try:
        table = read_csv_table(args.file, _choose(args.temperature_column))
    except (ValueError, RateFileError) as exc:
        raise CommandError(str(exc)) from None
    t = table.t_s
    assert t is not None
    if len(t) < 3 or not np.all(np.isfinite(table.values)) or not np.all(np.isfinite(t)):
        raise CommandError(f"{args.file}: needs finite times, rates and temperatures")
    die = limits.DIE_TEMPERATURE_C
    bad = np.flatnonzero((table.values[:, 3] < die.low) | (table.values[:, 3] > die.high))
    if bad.size:
        try:
            die.check(float(table.values[bad[0], 3]), table.where(bad[0]))
        except limits.LimitError as exc:
            raise CommandError(str(exc)) from None
    try:  # strictly increasing, named by line (a thermal log may pause: no gap check)
        step = check_time_column(t, table.where, gap_factor=math.inf)
    except RateFileError as exc:
        raise CommandError(str(exc)) from None
    rate_hz = 1.0 / step
    _check_blocks(block_s, step, len(t), args.block)
    noise = None
    if args.noise_profile is not None:
        from bmg160_emu.noise import load_profile

        try:
            noise = load_profile(args.noise_profile).axes
        except ValueError as exc:
            raise CommandError(str(exc)) from None
    try:
        fit = fit_bias_temperature(table.values[:, :3], table.values[:, 3], rate_hz,
                                   order=args.order, reference_c=args.reference,
                                   block_s=block_s, noise=noise)
    except (ThermalFitError, IdentificationError) as exc:  # the residuals' noise fit too
        raise CommandError(f"{args.file}: {exc}") from None
    try:  # made before any file is opened: a value TOML cannot hold is refused here
        outputs = [(path, text()) for path, text in (
            (args.px4_params, lambda: fit.px4_params_file(instance=args.px4_instance)),
            (args.errors_out, lambda: _errors_toml(fit.to_errors(), args.file)))
            if path is not None]
    except ValueError as exc:
        raise CommandError(f"{args.file}: {exc}") from None
    try:  # both or neither (io.atomic.write_together), each named by its own error
        write_together([(path, partial(_write_text, text)) for path, text in outputs])
    except OutputError as exc:
        raise CommandError(str(exc)) from None
    print(json.dumps(_as_dict(fit), indent=1) if args.json else _summary(fit, args.file))
    return 0


def _check_blocks(block_s: float, step_s: float, samples: int, shown: str) -> None:
    """A block of whole samples, and few enough of them for the fit's blocks x blocks
    covariance (limits.THERMAL_BLOCKS). ``--block 1ms`` on a 100 Hz log made one block per
    sample, and the covariance of a 1-hour log asked numpy for 966 GiB (issue 35)."""
    from bmg160_emu.commands._common import CommandError

    if block_s < step_s * (1 - 1e-9):
        raise CommandError(f"--block {shown} is shorter than the log's sample period "
                           f"({step_s:g} s): a block averages whole samples")
    per_block = max(1, round(block_s / step_s))
    blocks = samples // per_block
    most = int(limits.THERMAL_BLOCKS.high)
    if blocks > most:
        shortest = math.ceil(samples / most) * step_s
        raise CommandError(f"--block {shown} cuts the log into {blocks:,} blocks; the fit takes "
                           f"at most {most:,} (its covariance is blocks x blocks numbers, "
                           f"docs/limits.md): give --block {shortest:g}s or longer")


def _as_dict(fit: Any) -> dict[str, Any]:
    return {
        "reference_c": fit.reference_c, "order": fit.order, "block_s": fit.block_s,
        "temperature_range_c": list(fit.temperature_range_c),
        "axes": {name: {"coefficients": a.coefficients.tolist(),
                        "intervals_95": a.intervals.tolist(),
                        "reduced_chi2": a.reduced_chi2,
                        "noise": {"N": a.noise.N, "poles": [list(p) for p in a.noise.poles],
                                  "K": a.noise.K}}
                 for name, a in zip(fit.axis_names, fit.axes)},
        "px4": fit.px4_parameters(),
    }


def _summary(fit: Any, source: Path) -> str:
    lines = [(f"{source}: bias = c0 + c1 dT + c2 dT^2 + c3 dT^3, dT = T - {fit.reference_c:.2f} C, "
             f"over {fit.temperature_range_c[0]:.1f}..{fit.temperature_range_c[1]:.1f} C "
             f"(blocks of {fit.block_s:g} s; 95 % intervals)")]
    units = ("deg/s", "deg/s/K", "deg/s/K^2", "deg/s/K^3")
    for name, a in zip(fit.axis_names, fit.axes):
        for k in range(fit.order + 1):
            lo, hi = a.intervals[k]
            place = _last_digit_place(a.standard_errors[k])
            lines.append(f"  {name}  c{k} = {_to_place(a.coefficients[k], place, ' ')} "
                         f"{units[k]}  [{_to_place(lo, place)}, {_to_place(hi, place)}]")
        lines.append(f"  {name}  reduced chi-square {a.reduced_chi2:.2f}")
    return "\n".join(lines)


def _last_digit_place(standard_error: float) -> int:
    """The decimal place (a power of ten) of a standard error's second significant digit: an
    estimate is quoted to that place and no further (GUM, JCGM 100:2008, 7.2.6). The digits
    beyond it are noise, and they differ with the BLAS kernel of the machine."""
    if not (standard_error > 0 and math.isfinite(standard_error)):
        return -6
    return math.floor(math.log10(standard_error)) - 1


def _to_place(value: float, place: int, sign: str = "") -> str:
    """``value`` rounded to the decimal place ``10**place``, in the shortest notation."""
    if value == 0 or not math.isfinite(value):
        return f"{value:{sign}g}"
    digits = max(1, math.floor(math.log10(abs(value))) - place + 1)
    keep_zeros = "#" if digits > 1 else ""  # 0.01540, not 0.0154: the place is the point
    return f"{value:{sign}{keep_zeros}.{digits}g}"


def _errors_toml(errors: dict[str, Any], source: Path) -> str:
    """The fit as a profile's ``[errors]`` table (noise.profile_writer), under a comment
    naming the log it came from."""
    from bmg160_emu.noise.profile_writer import errors_table_lines, toml_comment

    lines = toml_comment(f"bmg160-emu thermal fit of {source}") + errors_table_lines(errors)
    return "\n".join(lines) + "\n"


def _write_text(text: str, path: Path) -> None:
    path.write_text(text, encoding="utf-8")
